"""The exceptions fmm_ros raises when it refuses data, so callers can tell bad data from bugs.

Every refusal is an `FmmError`. It stays a `ValueError` (the `fmm` command and older callers
catch those), but a campaign, a node or a test that catches `FmmError` knows the data was
refused with a reason, while any other exception is a fault in the code.

    FmmError
    ├── BadInputError        an argument, option, column, channel or field that cannot be used
    │   └── UnitError        a unit no table knows, or the wrong kind of unit for a channel
    ├── DamagedFileError     a file that is truncated, corrupt or not what its name says
    ├── NoCleanImpactError   too few clean impacts for what was asked
    │   └── SelectionError   ... carrying the selection that left the others out
    ├── FitError             records the model cannot explain (`reason`: one of FIT_FAILURES)
    ├── Infeasible           parameters the model cannot be evaluated at (a fit steps back)
    └── SourceStartTimeout   a source whose consumers did not appear in time (a RuntimeError too)

Bag I/O adds its own members under `FmmError` (`fmm_ros.io.bags.errors`).
"""


class FmmError(ValueError):
    """Data or input that fmm_ros refuses; the message names the problem in a user's words."""


class BadInputError(FmmError):
    """An argument, option, column, channel or field that cannot be used as given."""


class UnitError(BadInputError):
    """A unit that no table converts, or a unit of another kind than the channel's."""


class DamagedFileError(FmmError):
    """A file that is truncated, corrupt, or not the format its content or name claims."""


class NoCleanImpactError(FmmError):
    """Too few clean impacts for what was asked (a fit, a diagnosis, an FRF average)."""


class SelectionError(NoCleanImpactError):
    """Too few clean impacts for what was asked; `selection` says which were left out.

    `selection` is the `fmm_ros.core.signal.analysis.ImpactSelection` that refused them (not
    imported here: this module imports nothing, so every layer can raise its refusals).
    """

    def __init__(self, message: str, selection: object) -> None:
        super().__init__(message)
        self.selection = selection


FIT_FAILURES = (
    'no_hit',
    'no_motion',
    'mu_at_bound',
    'at_bound',
    'unexplained',
    'no_convergence',
    'too_few_cycles',
)
"""Why a fit refused its records: `FitError.reason`, what the CLI and the services report."""


class FitError(FmmError):
    """A record or set of records the model cannot explain; `reason` is one of FIT_FAILURES."""

    def __init__(self, reason: str, message: str, source: str = '') -> None:
        if reason not in FIT_FAILURES:
            raise BadInputError(f'unknown fit failure reason {reason!r}')
        self.reason = reason
        self.source = source
        super().__init__(f'{source}: {message}' if source else message)


class Infeasible(FmmError):
    """The model cannot be evaluated at these parameters (e.g. a friction coefficient < 0).

    A residual function raises it; Levenberg-Marquardt (`fmm_ros.core.identify.lsq`) takes
    it as a step that raised the cost, and refuses only a start point that raises it.
    """


class SourceStartTimeout(FmmError, RuntimeError):
    """A source's consumers did not all appear in time: it stops rather than lose samples.

    `fmm_ros.ros.common.run_node` exits 1 with the reason; `fmm_ros.ros.flow.FlowGate` raises
    it. Also a RuntimeError: the graph failed to come up, not the data.
    """
