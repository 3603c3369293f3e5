"""The acquisition chain: what the fit takes off the velocity, what the simulated rig adds.

ROS-free: `core.identify.chain` (mains hum, offset and drift estimated from a residual),
`output_error.spectral_score` (standard errors from the residual's own spectrum), and
`sim.daq` (the chain the simulated rig's channels pass through).
"""

import math

import numpy as np
import pytest
import scipy.signal
from fit_records import lab_levels

from fmm_ros.core import identify as fit
from fmm_ros.core.identify.chain import (
    DriftBasis,
    estimate_nuisance,
    hum_period_samples,
    mains_hum,
)
from fmm_ros.core.identify.output_error import spectral_score
from fmm_ros.sim.daq import ChainStream, ChannelChain

RATE_HZ = 10_000.0
N = 330_000


def _hum(frequency_hz, amplitude, n=N, rate=RATE_HZ):
    t = np.arange(n) / rate
    return amplitude * (
        np.sin(2 * np.pi * frequency_hz * t + 0.3) + 0.3 * np.sin(6 * np.pi * frequency_hz * t)
    )


@pytest.mark.parametrize('mains_hz, off_hz', [(50.0, 0.0), (60.0, 0.0), (50.0, 0.04)])
def test_mains_hum_is_found_and_taken_off(mains_hz, off_hz):
    rng = np.random.default_rng(int(mains_hz + 100 * off_hz))
    noise = rng.normal(0.0, 1e-4, N)
    hum = _hum(mains_hz + off_hz, 5e-5)
    found = mains_hum(noise + hum, RATE_HZ, 1e-4)
    assert found is not None and found.mains_hz == mains_hz
    out = np.zeros(N)
    found.add_to(out)
    # Little of the hum is left, even 0.04 Hz off the nominal frequency...
    left = (hum - out) @ hum / (hum @ hum)
    assert abs(left) < (0.1 if off_hz else 0.01)
    # ... and the noise is left as it was, less the degrees of freedom used (one period's
    # samples a 2 s segment: 1 % at 50 Hz, 2.4 % at 60 Hz, whose period is 3 cycles).
    dof = found.waveforms.size
    assert dof < 0.025 * N
    cleaned = noise + hum - out
    assert np.std(cleaned) == pytest.approx(1e-4 * math.sqrt(1 - dof / N), rel=0.01)


def test_no_hum_is_found_in_noise_and_nothing_is_taken_off():
    hits = 0
    for seed in range(20):
        noise = np.random.default_rng(seed).normal(0.0, 1e-4, N)
        hits += mains_hum(noise, RATE_HZ, 1e-4) is not None
    assert hits == 0


def test_hum_periods_are_whole_numbers_of_samples():
    assert hum_period_samples(10_000.0, 50.0) == 200
    assert hum_period_samples(10_000.0, 60.0) == 500  # 3 cycles
    assert hum_period_samples(5_000.0, 60.0) == 250
    assert hum_period_samples(12_800.0, 60.0) == 640
    assert hum_period_samples(10_000.0, 50.0 + math.pi / 1000) is None


def test_a_drifting_offset_is_estimated_beside_the_hum():
    rng = np.random.default_rng(3)
    line = 2e-5 + 1e-6 * np.arange(N) / RATE_HZ  # 2e-5 m/s, creeping by 1e-6 m/s a second
    residual = rng.normal(0.0, 1e-4, N) + _hum(50.0, 5e-5) + line
    nuisance = estimate_nuisance(residual, RATE_HZ, 1e-4, hum=True, drift=True)
    assert nuisance.mains_hz == 50.0
    assert nuisance.offset_m_s == pytest.approx(2e-5, abs=1e-6)
    assert nuisance.drift_m_s2 == pytest.approx(1e-6, rel=0.1)  # 1.8e-8 standard error
    assert np.std(residual - nuisance.values_m_s) == pytest.approx(1e-4, rel=0.01)
    none = estimate_nuisance(residual, RATE_HZ, 1e-4, hum=False, drift=False)
    assert none.dof == 0 and not none.values_m_s.any()


def test_the_drift_basis_is_linear_between_knots_and_removes_its_own_span():
    basis = DriftBasis.of(N, RATE_HZ)
    assert basis.size == 9  # 33 s: knots 4.1 s apart
    knots = np.array([0.0, 1.0, -2.0, 0.5, 0.5, 3.0, 0.0, 1.0, 2.0]) * 1e-5
    curve = basis.curve(knots)
    np.testing.assert_allclose(basis.solve(basis.project(curve)), knots, rtol=1e-9, atol=1e-18)
    # The projection is the plain one, B^T v, of hats linear between knots.
    hats = basis.curve(np.eye(basis.size))
    assert np.abs(hats.sum(axis=0) - 1.0).max() < 1e-12
    oscillation = np.sin(2 * np.pi * 2.2 * np.arange(N) / RATE_HZ)
    np.testing.assert_allclose(basis.project(oscillation), hats @ oscillation, atol=1e-9)
    np.testing.assert_allclose(basis.gram, hats @ hats.T, rtol=1e-12)
    # It takes a drift off whole, and leaves what it cannot follow (a few-Hz oscillation).
    rows = np.vstack([curve, oscillation])
    basis.remove(rows)
    assert np.abs(rows[0]).max() < 1e-15
    assert rows[1] @ oscillation / (oscillation @ oscillation) > 0.999


def _autocovariance_score(rows, gamma):
    """sum_ij J_i J_j gamma(i - j), the exact score covariance, by brute force."""
    n = rows.shape[1]
    total = np.zeros((rows.shape[0], rows.shape[0]))
    for lag in range(-gamma.size + 1, gamma.size):
        g = gamma[abs(lag)]
        if lag >= 0:
            total += g * rows[:, lag:] @ rows[:, : n - lag].T
        else:
            total += g * rows[:, : n + lag] @ rows[:, -lag:].T
    return total


@pytest.mark.slow
def test_the_spectral_score_is_the_white_one_for_white_noise_and_counts_colour():
    rng = np.random.default_rng(5)
    n = 200_000
    t = np.arange(n) / RATE_HZ
    envelope = np.clip(1 - t / 12.0, 0, None)
    rows = np.vstack(
        [envelope * np.sin(2 * np.pi * 2.2 * t), envelope * np.cos(2 * np.pi * 2.2 * t)]
    )
    white = rng.normal(0.0, 1e-4, n)
    score = spectral_score(rows, white, 1e-8, RATE_HZ)
    np.testing.assert_allclose(score, 1e-8 * rows @ rows.T, rtol=0.15, atol=0.02 * 1e-8 * n)
    # Low-frequency coloured noise (an AR(1) process, correlation time 0.1 s) on top.
    a = math.exp(-1.0 / (0.1 * RATE_HZ))
    coloured = scipy.signal.lfilter([math.sqrt(1 - a * a) * 3e-5], [1, -a], rng.normal(size=n))
    gamma = (3e-5) ** 2 * a ** np.arange(int(2.0 * RATE_HZ))
    exact = 1e-8 * rows @ rows.T + _autocovariance_score(rows, gamma)
    score = spectral_score(rows, white + coloured, 1e-8, RATE_HZ)
    np.testing.assert_allclose(np.diag(score), np.diag(exact), rtol=0.25)
    assert np.diag(exact).min() > 3 * np.diag(1e-8 * rows @ rows.T).max()


def _lab_chain_records(seed, chain):
    """Three lab records whose velocity went through a `sim.daq` chain."""
    records = lab_levels(seed, mu=0.113)
    out = []
    for index, record in enumerate(records):
        velocity = record.velocity_m_s.copy()
        ChainStream(chain, record.sample_rate_hz, seed=index).apply(0, velocity)
        out.append(fit.condition_impact(record.force_n, velocity, record.sample_rate_hz))
    return out


@pytest.mark.slow
def test_fit_friction_takes_hum_offset_and_drift_off_the_velocity():
    chain = ChannelChain(offset=5e-5, drift_per_sqrt_s=1e-5, hum_amplitude=5e-5, mains_hz=60.0)
    impacts = _lab_chain_records(12, chain)
    result = fit.fit_friction(impacts)
    assert result.mu == pytest.approx(0.113, rel=1e-3)
    assert abs(result.mu - 0.113) < 4 * result.mu_stderr
    for nuisance in result.joint.velocity_nuisance:
        assert nuisance.mains_hz == 60.0
        assert nuisance.offset_m_s == pytest.approx(5e-5, abs=3e-5)
    assert result.joint.residual_rms_m_s == pytest.approx(1e-4, rel=0.02)
    # As measured (the diagnosis's default), the same records leave the chain in the residual.
    raw = fit.fit_model(impacts)
    assert raw.residual_rms_m_s > 1.05e-4
    assert all(n.mains_hz == 0.0 and n.dof == 0 for n in raw.velocity_nuisance)


def test_the_simulated_chain_is_the_same_whatever_the_batches():
    chain = ChannelChain(anti_alias_order=4, offset=1e-5, drift_per_sqrt_s=1e-5, hum_amplitude=5e-5)
    signal = np.random.default_rng(0).normal(size=20_000)
    whole = ChainStream(chain, RATE_HZ, seed=3).apply(0, signal.copy())
    stream, parts, first = ChainStream(chain, RATE_HZ, seed=3), [], 0
    for size in (1, 499, 3000, 7000, 9500):
        parts.append(stream.apply(first, signal[first : first + size].copy()))
        first += size
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    with pytest.raises(ValueError, match='does not follow the last one'):
        stream.apply(first + 5, np.zeros(10))


def test_the_simulated_chain_filters_picks_up_hum_and_drifts():
    n = 400_000
    hum = ChainStream(ChannelChain(hum_amplitude=1.0, mains_hz=60.0), RATE_HZ, 1).apply(
        0, np.zeros(n)
    )
    spectrum = np.abs(np.fft.rfft(hum)) * 2 / n
    frequency = np.fft.rfftfreq(n, 1 / RATE_HZ)
    for order in (1, 2, 3, 5):
        assert spectrum[np.argmin(np.abs(frequency - 60.0 * order))] == pytest.approx(1 / order)
    assert spectrum.sum() == pytest.approx(1 + 1 / 2 + 1 / 3 + 1 / 5, rel=1e-6)
    # The anti-alias filter passes DC and stops Nyquist.
    filtered = ChainStream(ChannelChain(anti_alias_order=4), RATE_HZ, 1).apply(
        0, np.cos(np.pi * np.arange(4000)) + 2.0
    )
    assert filtered[-1000:] == pytest.approx(2.0, abs=1e-6)
    # The drift is a random walk: its spread after t seconds grows as sqrt(t).
    ends = [
        ChainStream(ChannelChain(drift_per_sqrt_s=1e-5), RATE_HZ, seed).apply(0, np.zeros(40_960))
        for seed in range(200)
    ]
    spread = np.std([end[-1] for end in ends])
    assert spread == pytest.approx(1e-5 * math.sqrt(4.0959), rel=0.15)
    with pytest.raises(ValueError, match='not below the Nyquist frequency'):
        ChainStream(ChannelChain(anti_alias_order=2, anti_alias_cutoff_hz=6000.0), RATE_HZ, 0)
