"""Contacts a world's motion is held to: lab's event-located DOP853 on the same physics.

Each row: the world's `Effects`, and the `plant.Contact` and `plant.Plant` that
`plant.solve_events` takes for them (Coulomb; damping with asymmetry; Stribeck; a softening
spring; a wear track), so every world written from scratch is checked on the same five.
`MIXED_CONTACTS` mixes effects in one contact (`bristle`, `newmark`), and `as_event_hit`
hands a world's own pulse to the DOP853 solver.
"""

from collections.abc import Callable

import numpy as np
from heldout.forces import Hit
from heldout.lab import Effects
from heldout.plant import Contact, Plant

REFERENCE_CONTACTS = (
    (Effects(), Contact(0.11), Plant()),
    (
        Effects(asymmetry=0.02, added_damping_n_s_per_m=0.3),
        Contact(0.11, asymmetry=0.02),
        Plant(damping_n_s_per_m=0.575),
    ),
    (
        Effects(static_excess=0.04, stribeck_speed_m_s=3e-3),
        Contact(0.11, static_excess=0.04, stribeck_speed_m_s=3e-3),
        Plant(),
    ),
    (Effects(cubic_n_per_m3=-6e4), Contact(0.11), Plant(cubic_n_per_m3=-6e4)),
    (
        Effects(track_amplitude=0.1, track_wavelength_m=6e-3),
        Contact(0.11, track_amplitude=0.1, track_wavelength_m=6e-3),
        Plant(),
    ),
)

MIXED_CONTACTS = (
    (Effects(), Contact(0.09), Plant()),
    (
        Effects(static_excess=0.05, stribeck_speed_m_s=2e-3, asymmetry=0.02, cubic_n_per_m3=6e4),
        Contact(0.09, static_excess=0.05, stribeck_speed_m_s=2e-3, asymmetry=0.02),
        Plant(cubic_n_per_m3=6e4),
    ),
    (
        Effects(track_amplitude=0.12, track_wavelength_m=5e-3, added_damping_n_s_per_m=0.3),
        Contact(0.09, track_amplitude=0.12, track_wavelength_m=5e-3),
        Plant(damping_n_s_per_m=0.575),
    ),
)
"""Coulomb; Stribeck, asymmetry and a cubic spring at once; a wear track with added damping."""


def as_event_hit(
    force_at: Callable[[float], float],
    force: Callable[[np.ndarray], np.ndarray],
    peak_n: float,
    onset_s: float,
    end_s: float,
) -> Hit:
    """A world's own hammer force as a `heldout.forces.Hit`, for lab's DOP853 event solver
    (which splits its spans at the hit's edges, onset_s and end_s)."""

    class SameForce(Hit):
        def force_at(self, time_s: float) -> float:
            return force_at(time_s)

        def force_n(self, time_s):
            return force(time_s)

        @property
        def end_s(self) -> float:
            return end_s

    return SameForce('half_sine', peak_n, end_s - onset_s, onset_s)
