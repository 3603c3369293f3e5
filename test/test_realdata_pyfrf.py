"""Real hammer hits of another lab (pyFRF, accelerometer, 25.6 kHz) through `fmm analyze`.

Five records of a free-free structure (`../shared/realdata/pyfrf_hammer`, README there): force
in N, acceleration in m/s^2. Each becomes the CSV a lab would write (`time_s, force_n,
acceleration_m_s2`), and what fmm reports is checked against a computation written here with
numpy alone: the impulse as the area of the pulse above the force's level before it, and H1,
H2 and coherence as sums of cross- and auto-spectra of the raw DFTs.
"""

import contextlib
import io
import json
from pathlib import Path

import numpy as np
import pytest

from fmm_ros.cli import main

REALDATA = Path(__file__).resolve().parents[1].parent / 'shared' / 'realdata' / 'pyfrf_hammer'
RECORDS = [REALDATA / f'measurements_{number}.npy' for number in range(1, 6)]
BAND_LIMIT_HZ = 6400.0
"""Up to where the FRFs are compared: a quarter of the 25.6 kHz rate (kHz modes)."""


def independent_impulse(force_n: np.ndarray, rate_hz: float) -> float:
    """Area of the pulse around the peak above the level before it (trapezoid, numpy alone)."""
    peak = int(np.argmax(force_n))
    start = peak
    while force_n[start - 1] >= 5.0:
        start -= 1
    level = force_n[:start].mean()
    above = force_n - level
    low, high = peak, peak
    while above[low] > 0:
        low -= 1
    while above[high] > 0:
        high += 1
    pulse = above[low : high + 1]
    return float((pulse[1:] + pulse[:-1]).sum() / 2 / rate_hz)


def independent_estimators(records: list[np.ndarray]) -> dict[str, np.ndarray]:
    """H1, H2 (accelerance) and coherence of the records from sums of raw DFT products."""
    forces = np.array([np.fft.rfft(record[1]) for record in records])
    accelerations = np.array([np.fft.rfft(record[2]) for record in records])
    g_ff = (forces.conj() * forces).real.sum(axis=0)
    g_aa = (accelerations.conj() * accelerations).real.sum(axis=0)
    g_fa = (forces.conj() * accelerations).sum(axis=0)
    return {
        'h1': g_fa / g_ff,
        'h2': g_aa / g_fa.conj(),
        'coherence': np.abs(g_fa) ** 2 / (g_ff * g_aa),
    }


@pytest.fixture(scope='module')
def hits(tmp_path_factory) -> tuple[list[np.ndarray], list[Path]]:
    """The five records, and each as the CSV file a lab would write."""
    folder = tmp_path_factory.mktemp('pyfrf')
    records, paths = [], []
    for number, source in enumerate(RECORDS, 1):
        record = np.load(source)
        path = folder / f'hit{number}.csv'
        np.savetxt(
            path,
            record.T,
            delimiter=',',
            header='time_s,force_n,acceleration_m_s2',
            comments='',
            fmt='%.17g',
        )
        records.append(record)
        paths.append(path)
    return records, paths


@pytest.fixture(scope='module')
def analysed(hits, tmp_path_factory) -> tuple[dict, dict[str, np.ndarray]]:
    """`fmm analyze` of the five files: its JSON and its level FRFs CSV (columns by name)."""
    _, paths = hits
    levels = tmp_path_factory.mktemp('out') / 'levels.csv'
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        code = main(
            [
                'analyze',
                *map(str, paths),
                '--band-limit-hz',
                str(BAND_LIMIT_HZ),
                '--json',
                '-o',
                str(levels),
            ]
        )
    assert code == 0
    table = np.genfromtxt(levels, delimiter=',', names=True)
    return json.loads(printed.getvalue()), {name: table[name] for name in table.dtype.names}


@pytest.mark.slow
def test_every_hit_is_clean_with_the_impulse_of_its_pulse(hits, analysed):
    records, _ = hits
    report, _ = analysed
    impacts = report['impacts']
    assert len(impacts) == len(records)
    for impact, record in zip(impacts, records, strict=True):
        assert impact['accepted'] and impact['flags'] == []
        rate = 1.0 / np.mean(np.diff(record[0]))
        expected = independent_impulse(record[1], rate)
        assert impact['impulse_n_s'] == pytest.approx(expected, rel=1e-9)
        assert 0.012 < impact['impulse_n_s'] < 0.016  # metal-tip pulses of 0.3 ms (README)
        assert impact['peak_force_n'] == pytest.approx(record[1].max(), rel=1e-12)
    assert [level['count'] for level in report['levels']] == [5]


@pytest.mark.slow
def test_h1_h2_and_coherence_match_numpy_in_all_three_forms(hits, analysed):
    records, _ = hits
    _, table = analysed
    frequency = table['frequency_hz']
    expected = independent_estimators(records)
    bins = frequency.size
    assert frequency[-1] == pytest.approx(BAND_LIMIT_HZ)
    omega = 2j * np.pi * frequency[1:]  # from the first bin on: DC holds no integrated FRF
    for estimator in ('h1', 'h2'):
        accelerance = expected[estimator][1:bins]
        for form, factor in (
            ('accelerance', 1),
            ('mobility', 1 / omega),
            ('receptance', 1 / omega**2),
        ):
            measured = (
                table[f'level_1_{estimator}_{form}_real']
                + 1j * table[f'level_1_{estimator}_{form}_imag']
            )
            np.testing.assert_allclose(measured[1:], accelerance * factor, rtol=1e-9)
    np.testing.assert_allclose(
        table['level_1_coherence'][1:], expected['coherence'][1:bins], rtol=1e-9
    )
    # The mass line of a free-free structure below its first mode: about 1.17 (m/s^2)/N,
    # inverted in sign (README), where the coherence of five real hits is near 1.
    low = (frequency > 20) & (frequency < 200)
    h1 = table['level_1_h1_accelerance_real'] + 1j * table['level_1_h1_accelerance_imag']
    assert np.median(np.abs(h1[low])) == pytest.approx(1.17, rel=0.05)
    assert np.median(table['level_1_coherence'][low]) > 0.99
