"""The rig constants of Eq. 3, and what a simulated run of the oscillator takes besides them.

`Rig` is what every model run, fit and node parameter table takes; `FMM_RIG` is the paper's
machine (Kossack, Ziegert, Schmitz 2019, Sec. 4): m = 10.391 kg, k = 1982 N/m,
c = 0.275 N*s/m and N = 0.680 kg x g. `PlantRun` declares a simulated plant's friction,
start and integrator, the settings of `fmm simulate`, `fmm demo` and the rig_sim node.
"""

import math
from dataclasses import dataclass

from fmm_ros.constants import PAPER_MU, SAMPLE_RATE_HZ
from fmm_ros.core.settings import require_non_negative, require_positive, setting

STANDARD_GRAVITY_M_S2 = 9.81


FMM_NORMAL_LOAD_KG = 0.680
"""Dead-weight mass on the pin's shaft that sets the FMM normal force."""


@dataclass(frozen=True)
class Rig:
    """Linear constants of the friction oscillator; defaults are the paper's FMM (Sec. 4)."""

    mass_kg: float = setting(10.391, unit='kg', help='Moving mass m', limits=(1e-3, 1e4))
    stiffness_n_per_m: float = setting(
        1982.0, unit='N/m', help='Flexure stiffness k', limits=(1e-3, 1e9)
    )
    damping_n_s_per_m: float = setting(
        0.275,
        unit='N*s/m',
        help='Viscous damping c (a fit of c starts from it)',
        limits=(0.0, 1e6),
    )
    normal_force_n: float = setting(
        FMM_NORMAL_LOAD_KG * STANDARD_GRAVITY_M_S2,
        unit='N',
        help=f'Normal force on the pin N ({FMM_NORMAL_LOAD_KG:.3f} kg x '
        f'{STANDARD_GRAVITY_M_S2} m/s^2 on the FMM)',
        limits=(0.0, 1e5),
    )

    def __post_init__(self) -> None:
        require_positive('mass_kg', self.mass_kg)
        require_positive('stiffness_n_per_m', self.stiffness_n_per_m)
        require_non_negative('damping_n_s_per_m', self.damping_n_s_per_m)
        require_non_negative('normal_force_n', self.normal_force_n)

    @property
    def natural_frequency_hz(self) -> float:
        """Undamped natural frequency f_n = sqrt(k/m) / 2 pi [Hz]."""
        return math.sqrt(self.stiffness_n_per_m / self.mass_kg) / (2.0 * math.pi)

    @property
    def damping_ratio(self) -> float:
        """Viscous damping ratio zeta = c / (2 sqrt(k m))."""
        return self.damping_n_s_per_m / (2.0 * math.sqrt(self.stiffness_n_per_m * self.mass_kg))

    def friction_limit_m(self, mu: float) -> float:
        """x_lim = mu N / k: the rest band half-width of the Coulomb oscillator [m]."""
        return mu * self.normal_force_n / self.stiffness_n_per_m


FMM_RIG = Rig()

INTEGRATORS = ('exact', 'rk4', 'euler')
"""How the oscillator is stepped: exactly between located stick/slip events, by RK4, or by the
paper's fixed-step Euler reference."""

# Length of a simulated run without a force record [s].
SIMULATED_DURATION_S = 33.0


@dataclass(frozen=True)
class PlantRun:
    """A simulated run of the oscillator besides its rig: friction, start, integrator, length.

    duration_s, sample_rate_hz: None takes the force record's (without one,
    SIMULATED_DURATION_S at SAMPLE_RATE_HZ); given with a record, a longer duration continues
    it with zero force and the rate must match the record's.
    """

    mu: float = setting(
        PAPER_MU, unit='-', help='Coulomb friction coefficient of the plant', limits=(0.0, 2.0)
    )
    x0_m: float = setting(0.0, unit='m', help='Initial displacement', limits=(-1.0, 1.0))
    v0_m_s: float = setting(0.0, unit='m/s', help='Initial velocity', limits=(-100.0, 100.0))
    integrator: str = setting(
        'exact',
        help="Physics integrator (euler: the paper's fixed-step reference)",
        choices=INTEGRATORS,
    )
    duration_s: float | None = setting(
        None,
        unit='s',
        help=f"Record length (none: the force record's, else {SIMULATED_DURATION_S:g} s; a "
        'longer one continues with zero force)',
        limits=(0.0, 1e5),
    )
    sample_rate_hz: float | None = setting(
        None,
        unit='Hz',
        help=f"Sample rate (none: the force record's, else {SAMPLE_RATE_HZ:g} Hz; with a "
        'record it must match)',
        limits=(1.0, 1e7),
    )
