"""fmm_ros.core.diagnose.signatures: noise, residual by region and band, decay signatures, peaks."""

import math

import numpy as np
import pytest

from fmm_ros.core.diagnose import signatures as d
from fmm_ros.core.identify.conditioning import velocity_noise_std
from fmm_ros.core.physics.model import free_vibration, simulate
from fmm_ros.core.physics.rig import FMM_RIG
from fmm_ros.core.physics.terms import model_term

RATE_HZ = 10_000.0
F_N = FMM_RIG.natural_frequency_hz


def test_excess_rms_subtracts_the_noise_and_never_goes_negative():
    rng = np.random.default_rng(2)
    noise = rng.normal(0.0, 1.0, 400_000)
    # mean r^2 scatters by sqrt(2 / n) about 1, so the floor is about (2 / n)^(1/4) = 0.047
    assert d.excess_rms(noise, 1.0) < 0.1
    assert d.excess_rms(noise + 2.0, 1.0) == pytest.approx(2.0, rel=0.01)
    assert d.excess_rms(noise, 1.5) == 0.0
    assert d.excess_rms(np.empty(0), 1.0) == 0.0


def coulomb_decay(duration_s=6.0, mu=0.113):
    force = np.zeros(round(duration_s * RATE_HZ))
    force[1000:1022] = 1000.0 * np.sin(np.pi * np.arange(22) / 22)
    return force, simulate(force, RATE_HZ, mu=mu).velocity_m_s


def test_region_labels_follow_the_decay():
    force, velocity = coulomb_decay()
    labels = d.region_labels(velocity, 1000)
    names = [d.REGIONS[i] for i in labels]
    assert set(names[:1000]) == {'at rest'}  # before the hit
    assert names[-1] == 'at rest'  # after the final stop
    moving = velocity != 0.0
    assert not np.any(labels[moving] == d.REGIONS.index('at rest'))
    early = np.flatnonzero(labels == d.REGIONS.index('early, large amplitude'))
    late = np.flatnonzero(labels == d.REGIONS.index('late, small amplitude'))
    assert early.size and late.size and early.max() < late.min()
    reversal = labels == d.REGIONS.index('near reversals')
    assert np.all(np.abs(velocity[reversal]) < 0.25 * np.abs(velocity).max())
    assert np.all(
        np.abs(velocity[labels == d.REGIONS.index('early, large amplitude')])
        >= 0.25 * 0.5 * np.abs(velocity).max()
    )


def test_time_regions_put_an_offset_at_rest_and_normalise_shares():
    force, velocity = coulomb_decay()
    rng = np.random.default_rng(3)
    residual = rng.normal(0.0, 1e-4, velocity.size) + 3e-4
    regions = {r.name: r for r in d.time_regions([residual], [velocity], [1000], 1e-4)}
    assert sum(r.share for r in regions.values()) == pytest.approx(1.0)
    total = sum(r.samples for r in regions.values())
    for region in regions.values():  # a uniform offset: each region's share is its size's
        assert region.share == pytest.approx(region.samples / total, abs=0.02)
    for region in regions.values():
        assert region.mean_m_s == pytest.approx(3e-4, abs=2e-5)
        assert region.excess_rms_m_s == pytest.approx(3e-4, rel=0.1)


@pytest.mark.parametrize(
    ('frequency_hz', 'band'),
    [(3 * F_N, 'odd harmonics'), (F_N, 'at f_n'), (3.4 * F_N, 'elsewhere'), (0.0, 'below f_n')],
)
def test_frequency_bands_find_the_band_of_a_residual_tone(frequency_hz, band):
    rng = np.random.default_rng(4)
    t = np.arange(330_000) / RATE_HZ
    residual = 3e-4 * np.cos(2 * np.pi * frequency_hz * t) + rng.normal(0.0, 1e-4, t.size)
    shares = {b.name: b.share for b in d.frequency_bands([residual], RATE_HZ, F_N, 1e-4)}
    assert shares[band] > 0.9
    assert sum(shares.values()) == pytest.approx(1.0)


def test_frequency_bands_of_pure_noise_hold_no_confident_band():
    rng = np.random.default_rng(5)
    residual = rng.normal(0.0, 1e-4, 330_000)
    bands = d.frequency_bands([residual], RATE_HZ, F_N, velocity_noise_std(residual))
    excess = sum(b.share for b in bands)
    assert excess in (0.0, pytest.approx(1.0))


def test_coulomb_decay_is_linear_with_unit_peak_map_slope():
    # Fig. 2's oscillator: x_lim = mu N / k; each half swing shrinks by 2 x_lim.
    mu = 0.113
    sim = free_vibration(10e-3, 8.0, RATE_HZ, mu=mu)
    velocity = np.concatenate((np.zeros(100), sim.velocity_m_s))
    signature = d.decay_signatures(velocity, RATE_HZ, 100, F_N)
    x_lim = FMM_RIG.friction_limit_m(mu)
    assert signature.envelope_shape == 'linear'
    assert signature.half_cycles >= 10
    assert signature.peak_map_slope == pytest.approx(1.0, abs=0.01)
    assert signature.peak_map_intercept_m == pytest.approx(-2 * x_lim, rel=0.05)
    assert signature.half_period_s == pytest.approx(0.5 / F_N, rel=0.01)


def test_viscous_decay_is_exponential_with_the_damping_ratio_in_the_peak_map():
    rig = type(FMM_RIG)(damping_n_s_per_m=4.0)
    sim = free_vibration(10e-3, 12.0, RATE_HZ, mu=0.0, rig=rig)
    velocity = np.concatenate((np.zeros(100), sim.velocity_m_s))
    signature = d.decay_signatures(velocity, RATE_HZ, 100, F_N)
    assert signature.envelope_shape == 'exponential'
    assert signature.peak_map_slope == pytest.approx(
        math.exp(-math.pi * rig.damping_ratio), abs=2e-3
    )
    assert abs(signature.peak_map_intercept_m) < 2e-5


def test_stiffening_shortens_the_large_swings():
    base = free_vibration(15e-3, 6.0, RATE_HZ, mu=0.05)
    stiff = free_vibration(
        15e-3,
        6.0,
        RATE_HZ,
        mu=0.05,
        effects=model_term('cubic_stiffness', cubic_stiffness_n_per_m3=2e6),
    )
    slopes = [
        d.decay_signatures(
            np.concatenate((np.zeros(100), s.velocity_m_s)), RATE_HZ, 100, F_N
        ).half_period_amplitude_slope_s_per_m2
        for s in (base, stiff)
    ]
    # Duffing: dT/d(A^2) = -3 k3 T0 / (8 k), about -85 s/m^2 here.
    assert slopes[1] - slopes[0] == pytest.approx(-3 * 2e6 * (0.5 / F_N) / (8 * 1982), rel=0.2)


def test_too_short_a_record_has_undetermined_signatures():
    signature = d.decay_signatures(np.zeros(1000), RATE_HZ, 10, F_N)
    assert signature.envelope_shape == 'undetermined' and signature.half_cycles == 0


def test_phase_delay_reads_a_lag_of_the_velocity_channel():
    force, velocity = coulomb_decay()
    delayed = simulate(force, RATE_HZ, effects=model_term('sensor_delay', delay_s=2.5e-4))
    assert d.phase_delay_s(delayed.velocity_m_s, velocity, RATE_HZ, F_N) == pytest.approx(
        2.5e-4, rel=0.05
    )
    assert abs(d.phase_delay_s(velocity, velocity, RATE_HZ, F_N)) < 1e-9


def test_rest_velocity_is_the_measured_mean_where_the_model_rests():
    force, velocity = coulomb_decay()
    rng = np.random.default_rng(6)
    measured = velocity + 2e-4 + rng.normal(0.0, 1e-4, velocity.size)
    mean, error = d.rest_velocity(measured, velocity, 1000, 1e-4)
    assert mean == pytest.approx(2e-4, abs=5 * error)
    assert error < 1e-6


def test_non_harmonic_peaks_find_a_ringing_mode_and_skip_harmonics():
    rng = np.random.default_rng(7)
    t = np.arange(330_000) / RATE_HZ
    ring = np.where(t > 1.0, 5e-4 * np.exp(-(t - 1.0) / 0.3), 0.0)
    noise = rng.normal(0.0, 1e-4, t.size)
    mode = ring * np.sin(2 * np.pi * 47.3 * t)
    harmonic = ring * np.sin(2 * np.pi * 7 * F_N * t)
    peaks = d.non_harmonic_peaks([noise + mode], RATE_HZ, F_N, 1e-4)
    assert peaks and peaks[0].frequency_hz == pytest.approx(47.3, abs=0.3)
    assert d.non_harmonic_peaks([noise + harmonic], RATE_HZ, F_N, 1e-4) == ()
    found = d.non_harmonic_peaks([noise + harmonic], RATE_HZ, F_N, 1e-4, skip_harmonics=False)
    assert found and found[0].frequency_hz == pytest.approx(7 * F_N, abs=0.3)
    assert d.non_harmonic_peaks([noise], RATE_HZ, F_N, 1e-4) == ()
