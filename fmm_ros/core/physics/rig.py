"""The rig constants of Eq. 3: moving mass, flexure stiffness, viscous damping, normal force.

`Rig` is what every model run, fit and node parameter table takes; `FMM_RIG` is the paper's
machine (Kossack, Ziegert, Schmitz 2019, Sec. 4): m = 10.391 kg, k = 1982 N/m,
c = 0.275 N*s/m and N = 0.680 kg x g.
"""

import math
from dataclasses import dataclass

from fmm_ros.core._checks import (
    require_non_negative,
    require_positive,
)

STANDARD_GRAVITY_M_S2 = 9.81


FMM_NORMAL_LOAD_KG = 0.680
"""Dead-weight mass on the pin's shaft that sets the FMM normal force."""


@dataclass(frozen=True)
class Rig:
    """Linear constants of the friction oscillator; defaults are the paper's FMM (Sec. 4)."""

    mass_kg: float = 10.391
    stiffness_n_per_m: float = 1982.0
    damping_n_s_per_m: float = 0.275
    normal_force_n: float = FMM_NORMAL_LOAD_KG * STANDARD_GRAVITY_M_S2

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
