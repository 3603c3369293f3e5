"""
Free vibration with Coulomb friction (Figs. 2-4)
================================================

The paper's Sec. 3 oscillator (m = 1 kg, k = 5000 N/m, no viscous damping, μ = 0.1,
N = m g) released at rest from 3 mm and from 1 mm. Friction takes a constant 4μN/k of
amplitude each cycle, so the peaks fall on straight lines, and the mass stops wherever the
spring can no longer overcome static friction: within ±μN/k of zero, seldom at zero.
"""

from fmm_ros.constants import SAMPLE_RATE_HZ
from fmm_ros.core.physics.model import free_vibration
from fmm_ros.report.paper import (
    FREE_VIBRATION_S,
    PAPER_OSCILLATOR,
    PAPER_OSCILLATOR_MU,
    SWEEP_X0_M,
    free_vibration_figure,
    rest_position_figure,
    rest_positions,
)

limit_m = PAPER_OSCILLATOR.friction_limit_m(PAPER_OSCILLATOR_MU)
for x0_m in (3e-3, 1e-3):
    run = free_vibration(
        x0_m, FREE_VIBRATION_S, SAMPLE_RATE_HZ, mu=PAPER_OSCILLATOR_MU, rig=PAPER_OSCILLATOR
    )
    print(f'released from {x0_m * 1e3:g} mm: at rest at {run.rest_position_m * 1e3:.3f} mm')
    free_vibration_figure(run, x0_m, limit_m)

# %%
# Final against initial displacement (Fig. 4): a triangle wave of period 4μN/k and amplitude
# μN/k, from one release per initial displacement.

finals = rest_positions(SWEEP_X0_M, mu=PAPER_OSCILLATOR_MU, rig=PAPER_OSCILLATOR)
rest_position_figure(SWEEP_X0_M, finals, limit_m)
