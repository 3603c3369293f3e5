"""What a friction fit is asked for (`FitSpec`): what it frees, its misfit, how it runs.

One typed, declared object (`fmm_ros.core.settings`) travels from the caller to the solver
instead of a dozen keyword arguments forwarded through `fit_model`, `fit_friction` and the
diagnosis. numpy-free, so the `fmm fit` options, the fitter's parameters and the docs can show
these without importing the fit.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from fmm_ros.constants import MISFIT_BAND_LIMIT_HZ
from fmm_ros.core.physics.rig import INTEGRATORS
from fmm_ros.core.settings import setting
from fmm_ros.errors import BadInputError

MU_BOUNDS = (1e-3, 1.0)
"""Default search range of the friction coefficient; a best fit on either end is a failure."""

MISFITS = ('time', 'frf')
"""What a fit minimises: the velocity's time residual, or the mobility's misfit in a band."""

UNCERTAINTIES = ('spectral', 'blocks')
"""How the velocity residuals' share of a time fit's covariance is found: from the residual's
spectrum over the whole record (default), or from block sums of the score over the motion
(the older method: noisy where the motion lasts a few periods; kept as the reference
the uncertainty benchmark compares with)."""

CENTRE, FITTED, CHAINED = 'centre', 'fitted', 'chained'
STARTS = (CENTRE, FITTED, CHAINED)
"""Where a fit starts each hit's model: at the centre (x = 0, the paper's isolated hits), at a
fitted start (a nuisance per hit, which absorbs a direction-dependent friction: see
`chained_starts`), or chained (the first hit at the centre, each later one where the model's
own run of the hit before came to rest)."""


def start_options(starts: str) -> dict[str, bool]:
    """The FitSpec fields (and `diagnose` keywords) of one of STARTS: `FitSpec.starts` undone."""
    if starts not in STARTS:
        raise BadInputError(f'unknown starts {starts!r}; choose one of {", ".join(STARTS)}')
    return {'fit_initial_position': starts == FITTED, 'chain_starts': starts == CHAINED}


JACOBIANS = ('blocks', 'dense')
"""How fit_model builds its Jacobian: 'blocks' runs and stores an impact's own parameters
(its start position) on that impact alone; 'dense' runs every column over every impact (the
plain way, kept as the reference the blocks are checked and benchmarked against)."""


@dataclass(frozen=True)
class FitSpec:
    """What a friction fit frees besides mu, what it minimises and how (`fit_model`).

    The defaults are `fit_model`'s: the paper's fit of mu alone on clean records.
    `fit_friction` starts from `FRICTION_FIT` (the records as an acquisition delivers them).
    """

    mu_bounds: tuple[float, float] = setting(
        MU_BOUNDS,
        help='Search range of mu; a best fit on either end is refused',
        limits=(0.0, 10.0),
    )
    fit_damping: bool = setting(False, help='Fit the viscous damping c too')
    fit_initial_position: bool = setting(
        False,
        help='Fit where the rig rested before each hit (friction leaves it off centre after '
        'the previous one); off: every hit starts at x = 0, as in the paper',
    )
    chain_starts: bool = setting(
        False,
        help='Chain the starts: the first hit starts at the centre (lift the pin and let the '
        'flexure centre the rig before it), each later one where the model left the rig after '
        'the hit before; for one continuous session in hit order, nothing moving the rig '
        'between records. Replaces fit_initial_position: fitted starts absorb a '
        'direction-dependent friction, chained ones let it show',
    )
    fit_impulse_scale: bool = setting(
        False,
        help="Fit a factor on each hit's measured force (sampling, filtering and noise "
        'misstate the impulse by 1e-4 to 1e-2)',
    )
    remove_mains_hum: bool = setting(
        False, help='Estimate the mains hum in the velocity and take it off, refitting'
    )
    fit_velocity_drift: bool = setting(
        False, help='Estimate a drifting velocity offset and take it off, refitting'
    )
    mains_hz: float | None = setting(
        None, unit='Hz', help='Mains frequency (None: found, 50 or 60 Hz)', limits=(1.0, 1000.0)
    )
    misfit: str = setting('time', help='What the fit minimises', choices=MISFITS)
    band_limit_hz: float = setting(
        MISFIT_BAND_LIMIT_HZ,
        unit='Hz',
        help="Top of the mobility band of the 'frf' misfit",
        limits=(0.1, 1e6),
    )
    integrator: str = setting('exact', help='How the model is integrated', choices=INTEGRATORS)
    jacobian: str = setting('blocks', help='How the Jacobian is built', choices=JACOBIANS)
    judge_hit: bool = setting(
        False, help='Judge the velocity inside each hit window too (the diagnosis does)'
    )
    uncertainty: str = setting(
        'spectral', help="How a time fit's uncertainty is found", choices=UNCERTAINTIES
    )

    @property
    def starts(self) -> str:
        """Where each hit's model starts: one of STARTS ('chained' wins over 'fitted')."""
        if self.chain_starts:
            return CHAINED
        return FITTED if self.fit_initial_position else CENTRE

    def but(self, **changes: Any) -> FitSpec:
        """A copy with some fields changed (TypeError naming an unknown one)."""
        return dataclasses.replace(self, **changes) if changes else self


FRICTION_FIT = FitSpec(fit_impulse_scale=True, remove_mains_hum=True, fit_velocity_drift=True)
"""`fit_friction`'s default: each hit's impulse scale fitted, mains hum, velocity offset and
drift taken off (the records as a data acquisition delivers them)."""


@dataclass(frozen=True)
class AxisSpec:
    """How a driven axis's friction is identified: known spring, filters, what to fit (SI).

    The settings of `identify_axis_friction` and `fmm identify-friction`.
    """

    stiffness_n_per_m: float = setting(
        0.0,
        unit='N/m',
        help='Known spring between the axis and the frame; 0 for a free axis',
        limits=(0.0, 1e9),
    )
    cutoff_hz: float | None = setting(
        None,
        unit='Hz',
        help='Position low-pass cut-off (none: a tenth of the sample rate)',
        limits=(1e-3, 1e7),
    )
    decimation: int | None = setting(
        None,
        unit='-',
        help='Keep one sample in this many after the parallel filter (none: from the band)',
        limits=(1, 1_000_000),
    )
    per_direction: bool = setting(
        True, help='Also fit viscous and Coulomb friction for each direction of motion'
    )

    def __post_init__(self) -> None:
        if not math.isfinite(self.stiffness_n_per_m) or self.stiffness_n_per_m < 0.0:
            raise BadInputError(
                f'stiffness_n_per_m must be finite and >= 0, got {self.stiffness_n_per_m}'
            )
        if self.cutoff_hz is not None and not (self.cutoff_hz > 0.0):
            raise BadInputError(f'cutoff_hz must be positive, got {self.cutoff_hz}')
        if self.decimation is not None and self.decimation < 1:
            raise BadInputError(f'decimation must be at least 1, got {self.decimation}')
