"""The diagnosis of FMM sessions measured by an accelerometer.

The velocity integrated from an accelerometer carries a random walk, not white noise: the
diagnosis takes the sensor's drift off with the base model and describes what is left by
`converted_noise` (its density at the rig's natural frequency for evidence, the small
variance it leaves in a residual for the excess). Checked here: that description against
integrated white noise itself; sessions of `heldout.lab.ACCELEROMETER` (the description was
worked out on it: a tuning world) over several seeds, clean and hiding an effect; and the
held-out generator `accelerometer_records` through `fmm diagnose` on CSV files, as a lab runs
it. `benchmarks/bench_accelerometer_diagnosis.py` counts the rates over many more sessions.
"""

import numpy as np
import pytest
import scipy.signal
from accelerometer_records import session, write_csv
from heldout.cases import case
from heldout.lab import ACCELEROMETER

from fmm_ros.cli import main
from fmm_ros.core.diagnose import NONE, UNEXPLAINED, diagnose
from fmm_ros.core.identify.chain import DRIFT_KNOT_S, DriftBasis
from fmm_ros.core.identify.spec import start_options
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.core.signal.response import (
    ACCELERATION,
    DISPLACEMENT,
    VELOCITY,
    as_measured,
    converted_noise,
    velocity_from_response,
)

SIGMA_M_S2 = 2e-3


def test_integrated_white_noise_is_described_by_its_density_and_what_the_drift_leaves():
    rng = np.random.default_rng(4)
    fs, n = 10_000.0, 120_000
    density, left = [], []
    for _ in range(6):
        acceleration = rng.normal(0.0, SIGMA_M_S2, n)
        velocity = velocity_from_response(acceleration, ACCELERATION, fs, 0)
        frequency, power = scipy.signal.welch(velocity, fs, nperseg=40_000, detrend='linear')
        band = (frequency > 1.5) & (frequency < 3.0)  # about the rig's 2.2 Hz
        white = power[band] * (frequency[band] / 2.2) ** 2  # the 1/f^2 slope taken out
        density.append(np.sqrt(np.mean(white) * fs / 2.0))  # white noise of that density
        rows = velocity[None, :].copy()
        DriftBasis.of(n, fs).remove(rows)
        left.append(np.sqrt(np.mean(rows**2)))
    described = converted_noise(acceleration, ACCELERATION, fs, 2.2, DRIFT_KNOT_S)
    assert np.mean(density) == pytest.approx(described.band_std_m_s, rel=0.1)
    assert np.mean(left) == pytest.approx(described.residual_std_m_s, rel=0.25)
    # Both far from the white level its sample-to-sample changes show (sigma / fs / sqrt(12)).
    assert described.residual_std_m_s > 20 * SIGMA_M_S2 / fs
    plain = converted_noise(acceleration, VELOCITY, fs, 2.2, DRIFT_KNOT_S)
    assert plain.band_std_m_s == plain.residual_std_m_s == pytest.approx(SIGMA_M_S2, rel=0.05)


def test_differentiated_white_noise_is_described_alike():
    rng = np.random.default_rng(5)
    fs, sigma_m = 10_000.0, 1e-7
    position = rng.normal(0.0, sigma_m, 200_000)
    velocity = velocity_from_response(position, DISPLACEMENT, fs, 0)
    frequency, power = scipy.signal.welch(velocity, fs, nperseg=20_000)
    band = (frequency > 1.5) & (frequency < 3.0)
    white = power[band] * (2.2 / frequency[band]) ** 2  # the f^2 slope taken out
    described = converted_noise(position, DISPLACEMENT, fs, 2.2, DRIFT_KNOT_S)
    assert np.sqrt(np.mean(white) * fs / 2.0) == pytest.approx(described.band_std_m_s, rel=0.1)
    assert np.std(velocity) == pytest.approx(described.residual_std_m_s, rel=0.05)


def as_read(records) -> list:
    """The world's records as fmm reads an accelerometer: the velocity integrated."""
    return [
        as_measured(
            ImpactRecord(r.force_n, r.velocity_m_s, r.sample_rate_hz, source=r.source),
            r.quantity,
        )
        for r in records
    ]


@pytest.mark.slow
@pytest.mark.parametrize(
    'kind, seeds',
    [('none', (1, 2, 3)), ('stribeck', (4, 5)), ('second_mode', (6,)), ('wear_track', (7,))],
)
def test_accelerometer_sessions_get_the_vibrometer_answers(kind, seeds):
    for seed in seeds:
        records, hidden, starts = case(ACCELEROMETER, kind, np.random.default_rng([26, seed]))
        result = diagnose(as_read(records), **start_options(starts))
        if kind == 'wear_track':
            assert result.named_effects[:1] == (UNEXPLAINED,), result.verdict
        elif kind == 'none':
            assert result.missing_effect == NONE, result.verdict
        else:
            assert set(result.named_effects) == set(hidden), result.verdict
        assert result.noise_std_m_s > 1e-5  # the density, not the sample-to-sample level


@pytest.mark.slow
def test_fmm_diagnose_on_held_out_accelerometer_files(tmp_path, capsys):
    """Clean sessions say none; hidden damping is named; fit's mu stays within 0.5 %."""
    for seed, mu, added in ((12, 0.08, 0.0), (23, 0.12, 0.0), (21, 0.1, 0.8)):
        folder = tmp_path / str(seed)
        folder.mkdir()
        paths = [
            str(write_csv(folder / f'hit{number}.csv', force, acceleration))
            for number, (force, acceleration) in enumerate(session(mu, seed, added))
        ]
        assert main(['diagnose', *paths, '--fit-initial-position', '--json', '-q']) == 0
        answer = capsys.readouterr().out
        expected = '"viscous_damping"' if added else '"missing_effect": "none"'
        assert expected in answer, answer[:2000]
