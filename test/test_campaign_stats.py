"""The campaign's statistics: the textbook meta-analysis, and honest intervals by simulation.

The estimator is checked against the BCG vaccine trials (Colditz et al. 1994), the example of
Viechtbauer's metafor paper (J. Stat. Softw. 36(3), 2010) and of Borenstein et al.'s
Introduction to Meta-Analysis: the published tau^2, estimates and standard errors. Its
intervals are then checked where it matters for a lab: over many simulated campaigns (session
mu drawn from a random-effects model, not the product's simulator), the 95 % intervals of
condition differences must cover the truth about 95 % of the time, and a pair of conditions
with no real difference must be declared different at most about 5 % of the time.
"""

import math

import numpy as np
import pytest
from campaign_sessions import COLUMNS, LUBRICANTS, random_effects_campaign

from fmm_ros.campaign.compare import SessionMu, compare_sessions
from fmm_ros.campaign.stats import holm, meta_regression

# BCG trials: vaccinated TB cases, vaccinated without, controls with TB, without; latitude.
BCG = np.array(
    [
        [4, 119, 11, 128, 44],
        [6, 300, 29, 274, 55],
        [3, 228, 11, 209, 42],
        [62, 13536, 248, 12619, 52],
        [33, 5036, 47, 5761, 13],
        [180, 1361, 372, 1079, 44],
        [8, 2537, 10, 619, 19],
        [505, 87886, 499, 87892, 13],
        [29, 7470, 45, 7232, 27],
        [17, 1699, 65, 1600, 42],
        [186, 50448, 141, 27197, 18],
        [5, 2493, 3, 2338, 33],
        [27, 16886, 29, 17825, 33],
    ],
    dtype=float,
)


def bcg_log_risk_ratios():
    tpos, tneg, cpos, cneg, latitude = BCG.T
    y = np.log(tpos / (tpos + tneg) / (cpos / (cpos + cneg)))
    v = 1 / tpos - 1 / (tpos + tneg) + 1 / cpos - 1 / (cpos + cneg)
    return y, v, latitude


def test_reml_random_effects_reproduces_the_bcg_textbook_numbers():
    y, v, _ = bcg_log_risk_ratios()
    fit = meta_regression(y, v, np.ones((13, 1)), ['mu'], knapp_hartung_floor=False)
    # metafor: rma(yi, vi): tau^2 = 0.3132 (SE 0.1664), estimate -0.7145 (SE 0.1798),
    # Q(12) = 152.2330, I^2 = 92.22 %.
    assert fit.tau2 == pytest.approx(0.3132, abs=5e-5)
    assert fit.tau2_stderr == pytest.approx(0.1664, abs=5e-5)
    assert fit.coefficients[0] == pytest.approx(-0.7145, abs=5e-5)
    assert math.sqrt(fit.model_covariance[0, 0]) == pytest.approx(0.1798, abs=5e-5)
    assert fit.heterogeneity_q == pytest.approx(152.2330, abs=5e-4)
    assert fit.i2 == pytest.approx(0.9222, abs=5e-5)
    # test='knha': SE 0.1808, t(12) CI -1.1084 to -0.3206, p = 0.0019.
    knha = fit.coefficient('mu')
    assert knha.stderr == pytest.approx(0.1808, abs=5e-5)
    assert (knha.ci_low, knha.ci_high) == pytest.approx((-1.1084, -0.3206), abs=5e-5)
    assert knha.p_value == pytest.approx(0.0019, abs=5e-5)
    assert knha.dof == 12


def test_dersimonian_laird_reproduces_the_bcg_textbook_numbers():
    y, v, _ = bcg_log_risk_ratios()
    fit = meta_regression(y, v, np.ones((13, 1)), tau2_method='dl')
    # metafor: rma(yi, vi, method='DL'): tau^2 = 0.3088, estimate -0.7141 (SE 0.1787).
    assert fit.tau2 == pytest.approx(0.3088, abs=5e-5)
    assert fit.coefficients[0] == pytest.approx(-0.7141, abs=5e-5)
    assert math.sqrt(fit.model_covariance[0, 0]) == pytest.approx(0.1787, abs=5e-5)


def test_meta_regression_on_latitude_reproduces_the_textbook_numbers():
    y, v, latitude = bcg_log_risk_ratios()
    fit = meta_regression(y, v, np.column_stack([np.ones(13), latitude]), ['intercept', 'lat'])
    # metafor: rma(yi, vi, mods = ~ ablat): tau^2 = 0.0764 (SE 0.0591), tau = 0.2763,
    # intercept 0.2515 (SE 0.2491), slope -0.0291 (SE 0.0072), residual Q_E(11) = 30.7331,
    # I^2 = 68.39 %. (metafor stops at a relative change of 1e-5 in tau^2; this fit goes on
    # to 0.07635, whose tau rounds the same.)
    assert fit.tau2 == pytest.approx(0.0764, abs=1e-4)
    assert fit.tau == pytest.approx(0.2763, abs=5e-5)
    assert fit.tau2_stderr == pytest.approx(0.0591, abs=1e-4)
    assert fit.coefficients == pytest.approx([0.2515, -0.0291], abs=5e-5)
    assert np.sqrt(np.diag(fit.model_covariance)) == pytest.approx([0.2491, 0.0072], abs=5e-5)
    assert fit.heterogeneity_q == pytest.approx(30.7331, abs=5e-4)
    assert fit.i2 == pytest.approx(0.6839, abs=5e-5)
    assert fit.dof == 11


def test_the_knapp_hartung_floor_never_narrows_the_model_errors():
    y, v, _ = bcg_log_risk_ratios()
    rng = np.random.default_rng(3)
    # Homogeneous data: q falls below 1 by chance, the floor keeps the model's own errors.
    same = rng.normal(0.0, np.sqrt(v))
    floored = meta_regression(same, v, np.ones((13, 1)))
    plain = meta_regression(same, v, np.ones((13, 1)), knapp_hartung_floor=False)
    assert floored.scale == max(1.0, plain.q_statistic)
    assert floored.covariance[0, 0] >= floored.model_covariance[0, 0]


def test_bad_input_is_refused_with_the_reason():
    with pytest.raises(ValueError, match='positive'):
        meta_regression([0.1, 0.2], [0.0, 1e-6], np.ones((2, 1)))
    with pytest.raises(ValueError, match='does not identify'):
        meta_regression([0.1, 0.2, 0.3], [1e-6] * 3, np.ones((3, 2)), ['a', 'b'])
    with pytest.raises(ValueError, match='finite'):
        meta_regression([0.1, math.nan], [1e-6] * 2, np.ones((2, 1)))


def test_holm_adjusts_step_down_and_keeps_order():
    # Holm (1979): sorted p 0.01, 0.02, 0.04 of 3 -> 0.03, 0.04, 0.04.
    assert holm([0.04, 0.01, 0.02]) == pytest.approx([0.04, 0.03, 0.04])
    assert holm([0.5, 0.9]) == pytest.approx([1.0, 1.0])
    assert np.isnan(holm([math.nan, 0.01])[0]) and holm([math.nan, 0.01])[1] == 0.01


# -- calibration by simulation ----------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize(
    ('sessions_per_condition', 'tau', 'sigma_median'),
    [
        (4, 0.002, 2e-5),  # the benchmark's campaign: scatter between sessions dominates
        (2, 0.002, 2e-5),  # two sessions a condition: few degrees of freedom
        (4, 0.0, 5e-4),  # no scatter between sessions: the fits' errors are all there is
        (4, 5e-4, 5e-4),  # both alike
    ],
)
def test_difference_intervals_cover_the_truth_and_null_pairs_are_rarely_declared(
    sessions_per_condition, tau, sigma_median
):
    """Over 600 campaigns: the main effects' 95 % intervals cover their truth (B - A =
    -0.012, C - A = 0) in 95 % of campaigns within binomial scatter, and C is declared
    different from A in at most ~5 %."""
    rng = np.random.default_rng(sessions_per_condition * 1000 + int(tau * 1e6))
    campaigns = 600
    covered, null_declared = [], []
    for _ in range(campaigns):
        comparison = compare_sessions(
            random_effects_campaign(rng, sessions_per_condition, tau, sigma_median),
            COLUMNS,
            ('lubricant', 'normal_force_n'),
        )
        main = {
            (d.level, d.reference): d
            for d in comparison.differences
            if d.column == 'lubricant' and d.averaged
        }
        for (level, reference), difference in main.items():
            truth = LUBRICANTS[level] - LUBRICANTS[reference]
            covered.append(difference.estimate.ci_low <= truth <= difference.estimate.ci_high)
        null_declared.append(main[('C', 'A')].different)
    coverage = np.mean(covered)
    # 1800 intervals (three per campaign, correlated within one): 95 % +- about 1.5 %.
    assert 0.93 <= coverage <= 0.985, coverage
    # Holm-adjusted over three pairs: at most 5 % family-wise, so this pair alone less.
    assert np.mean(null_declared) <= 0.06, np.mean(null_declared)


def test_a_real_difference_is_found_and_said_in_words():
    rng = np.random.default_rng(11)
    comparison = compare_sessions(
        random_effects_campaign(rng, 4, 0.002, 2e-5), COLUMNS, ('lubricant', 'normal_force_n')
    )
    b_vs_a = next(
        d
        for d in comparison.differences
        if d.averaged and (d.level, d.reference) == ('B', 'A') and d.column == 'lubricant'
    )
    assert b_vs_a.different and b_vs_a.estimate.estimate < 0
    sentence = next(v for v in comparison.verdicts if v.startswith('lubricant B'))
    assert sentence.startswith('lubricant B lowers mu by 0.01')
    assert 'against A (95 % CI' in sentence and 'Holm-adjusted' in sentence
    assert any(
        v.startswith('lubricant C and A: no detectable difference') for v in comparison.verdicts
    )


def test_a_linear_trend_against_a_numeric_column_is_recovered():
    """mu = 0.1 + 0.002 per N with session scatter: the common slope's interval covers it."""
    rng = np.random.default_rng(5)
    sessions = []
    for lubricant, offset in (('A', 0.0), ('B', -0.01)):
        for load in (4.0, 6.0, 8.0, 10.0):
            for number in range(3):
                mu = 0.1 + offset + 0.002 * (load - 7.0) + rng.normal(0.0, 0.001)
                sessions.append(
                    SessionMu(
                        f'{lubricant}{load}{number}',
                        {'lubricant': lubricant, 'normal_force_n': load},
                        mu,
                        1e-10,
                        10,
                    )
                )
    comparison = compare_sessions(sessions, COLUMNS, ('lubricant',), ('normal_force_n',))
    common = next(t for t in comparison.trends if t.group == 'all')
    assert common.slope.ci_low <= 0.002 <= common.slope.ci_high
    assert common.slope.p_value < 1e-4 and common.unit == 'N'
    per_group = [t for t in comparison.trends if t.group != 'all']
    assert [t.group for t in per_group] == ['A', 'B']
    assert any(v.startswith('mu rises with normal_force_n') for v in comparison.verdicts)


def test_one_session_a_condition_gives_estimates_but_no_interval():
    sessions = [
        SessionMu(name, {'lubricant': name, 'normal_force_n': 6.67}, mu, 1e-10, 5)
        for name, mu in (('A', 0.11), ('B', 0.10))
    ]
    comparison = compare_sessions(sessions, COLUMNS, ('lubricant',))
    assert [c.estimate.estimate for c in comparison.conditions] == pytest.approx([0.11, 0.10])
    assert all(math.isnan(d.estimate.p_value) and not d.different for d in comparison.differences)
    assert any('single session' in note for note in comparison.notes)
