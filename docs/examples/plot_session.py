"""
A measured session: levels, linearity, odd harmonics and μ (Figs. 13, 16, 17, 24)
=================================================================================

The paper's experiment in small: hits at 450, 1000 and 1450 N on the friction measuring
machine, force and velocity at 10 kHz, each hit a 33 s record. Here three hits a level come
from the simulated plant (μ = 0.113) with sensor noise, and go through the same capture,
analysis and fit as the analyzer and fitter nodes, ``fmm analyze`` and ``fmm fit``.
"""

from fmm_ros.core.identify.friction import fit_friction
from fmm_ros.core.signal.analysis import AnalysisConfig, paper_levels
from fmm_ros.core.signal.capture import CaptureConfig, capture_impacts
from fmm_ros.report.session_figures import (
    harmonics_figure,
    impulse_figure,
    level_magnitude_figure,
    linearity_figure,
)
from fmm_ros.sim.session import simulated_session
from fmm_ros.workflows.session import analyse

session = simulated_session(3, seed=7)
records = capture_impacts(session.force_n, session.velocity_m_s, session.sample_rate_hz)
summary = analyse(records, CaptureConfig(), AnalysisConfig(levels=paper_levels()))
for level in summary.levels:
    print(f'{level.level:7} {level.count} hits, impulse {level.mean_impulse_n_s:.3f} N·s')

# %%
# Peak force of every hit within its level's band, and each level's mean impulse (Fig. 13).

impulse_figure(summary.impacts, summary.levels, paper_levels())

# %%
# The mean receptance of each level grows with the force (Fig. 16) ...

level_magnitude_figure(summary.levels)

# %%
# ... linearly in the impulse (Fig. 17): the paper's first claim.

print(f'R² of peak |receptance| against impulse: {summary.linearity.r2:.4f}')
linearity_figure(summary)

# %%
# The sliding contact puts response at odd multiples of the natural frequency (Fig. 24).

harmonics_figure(summary.levels)

# %%
# The paper's second claim: one μ, fitted with the measured force driving the model of
# Eq. 3, serves every level. Each hit's own μ and a χ² test of one μ come with it.

fit = fit_friction(records)
print(f'μ = {fit.mu:.5f} ± {fit.mu_stderr:.1e} (plant {session.mu})')
print(f'one μ serves every hit: p = {fit.consistency_p_value:.2f}')
