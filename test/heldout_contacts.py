"""Contacts a world's motion is held to: lab's event-located DOP853 on the same physics.

Each row: the world's `Effects`, and the `plant.Contact` and `plant.Plant` that
`plant.solve_events` takes for them (Coulomb; damping with asymmetry; Stribeck; a softening
spring; a wear track), so every world written from scratch is checked on the same five.
"""

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
