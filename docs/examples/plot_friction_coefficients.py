"""
Three friction coefficients (Figs. 8-10)
========================================

The same 10 ms, 100 N pulse with μ = 0.05, 0.1 and 0.2: more friction stops the mass
sooner, and the receptance near the natural frequency falls as μ rises. This is what lets
the method read μ from the motion instead of from a force sensor.
"""

from fmm_ros.report.paper import (
    FRICTION_STUDY_MU,
    PULSE_DURATIONS_S,
    pulse_receptance_figure,
    pulse_response,
    pulse_spectra_figure,
    pulse_time_figure,
)

width_s = PULSE_DURATIONS_S[-1]
responses = [pulse_response(width_s, mu=mu, label=f'μ = {mu:g}') for mu in FRICTION_STUDY_MU]
pulse_time_figure(responses, decay_s=4.0, start_s=0.25)

# %%
# Spectra, and the displacement magnitude near f_n (Fig. 9).

pulse_spectra_figure(responses, zoom=True)

# %%
# Receptance for the three μ (Fig. 10).

pulse_receptance_figure(responses, zoom=True)
