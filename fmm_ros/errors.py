"""The exceptions fmm_ros raises when it refuses data, so callers can tell bad data from bugs.

Every refusal is an `FmmError`. It stays a `ValueError` (the `fmm` command and older callers
catch those), but a campaign, a node or a test that catches `FmmError` knows the data was
refused with a reason, while any other exception is a fault in the code.

    FmmError
    ├── BadInputError        an argument, option, column, channel or field that cannot be used
    │   └── UnitError        a unit no table knows, or the wrong kind of unit for a channel
    ├── DamagedFileError     a file that is truncated, corrupt or not what its name says
    └── NoCleanImpactError   too few clean impacts for what was asked
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
