"""
A rectangular pulse of three durations (Figs. 5-7)
==================================================

100 N for 2.5, 5 and 10 ms into the same oscillator, 25 s records at 10 kHz. The
displacement peaks fall linearly (friction), not exponentially (viscous damping), and the
receptance depends on the energy put in: unlike a linear system's, the FRF of a friction
contact is not one curve.
"""

from fmm_ros.report.paper import (
    PULSE_DURATIONS_S,
    PULSE_FORCE_N,
    pulse_receptance_figure,
    pulse_response,
    pulse_spectra_figure,
    pulse_time_figure,
)

responses = [
    pulse_response(width, label=f'Δt = {width * 1e3:g} ms ({PULSE_FORCE_N * width:g} N·s)')
    for width in PULSE_DURATIONS_S
]
for response in responses:
    print(f'{response.label}: at rest at {response.rest_position_m * 1e3:.3f} mm')
pulse_time_figure(responses)

# %%
# Force and displacement spectra (Fig. 6): the response peaks at the natural frequency.

pulse_spectra_figure(responses)

# %%
# Real and imaginary receptance (Fig. 7).

pulse_receptance_figure(responses)
