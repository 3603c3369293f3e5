"""NI's text exports: a BOM, `;`, decimal commas and date-time stamps as the time column.

The files are written here the way NI's exports lay them out (`27/03/2025 10:51:38,2226056`,
one stamp per sample, a PC clock's jitter on each), and read back through the lab-file path
every command takes: the rate must come from the stamps, the jitter be reported, and stamps
that go backwards be refused naming the row.
"""

import datetime

import numpy as np
import pytest

from fmm_ros.cli import main
from fmm_ros.errors import BadInputError
from fmm_ros.io.labfiles import read_lab_file
from fmm_ros.io.stamps import seconds_of_stamp

RATE_HZ = 1600.0
START = datetime.datetime(2025, 3, 27, 23, 59, 58)  # the record runs over midnight
START_FRACTION_S = 0.2226056


def stamp(seconds: float) -> str:
    """NI's day-first stamp with a decimal comma and 7 digits of the second."""
    ticks = round((seconds + START_FRACTION_S) * 1e7)
    whole, ticks = divmod(ticks, 10**7)
    return f'{START + datetime.timedelta(seconds=whole):%d/%m/%Y %H:%M:%S},{ticks:07d}'


def ni_export(path, force_n, acceleration_g, jitter_s=0.0, seed=0, swap_at=None):
    """Write an NI-style export: BOM, `;`, decimal commas, a stamp per sample."""
    rng = np.random.default_rng(seed)
    times = np.arange(force_n.size) / RATE_HZ + rng.uniform(-jitter_s, jitter_s, force_n.size)
    times[0] = 0.0
    if swap_at is not None:
        times[[swap_at, swap_at + 1]] = times[[swap_at + 1, swap_at]]
    rows = ['Zeit;Hammer;Beschleunigung', ';N;g']
    rows += [
        f'{stamp(t)};{f:.5f};{a:.6f}'.replace('.', ',')
        for t, f, a in zip(times, force_n, acceleration_g, strict=True)
    ]
    path.write_bytes(b'\xef\xbb\xbf' + '\r\n'.join(rows).encode('utf-8'))
    return path


def signals(seconds: float = 3.0) -> tuple[np.ndarray, np.ndarray]:
    """A hammer pulse at 1 s and a decaying 40 Hz acceleration (g) after it."""
    time_s = np.arange(int(seconds * RATE_HZ)) / RATE_HZ
    phase = (time_s - 1.0) / 0.005
    force = np.where((phase > 0) & (phase < 1), 120 * np.sin(np.pi * np.clip(phase, 0, 1)), 0.0)
    after = np.clip(time_s - 1.0, 0, None)
    acceleration = np.where(
        time_s > 1.0, np.sin(2 * np.pi * 40 * after) * np.exp(-after / 0.2), 0.0
    )
    return force, acceleration


def test_the_stamps_parse_exactly_day_first_and_iso():
    assert seconds_of_stamp('27/03/2025 10:51:38,2226056') == (
        datetime.date(2025, 3, 27).toordinal(),
        pytest.approx(10 * 3600 + 51 * 60 + 38.2226056, abs=1e-9),
    )
    assert seconds_of_stamp('2025-03-27 10:51:38.5')[1] == 10 * 3600 + 51 * 60 + 38.5


def test_rate_from_the_stamps_with_their_jitter_reported(tmp_path):
    force, acceleration = signals()
    path = ni_export(tmp_path / 'ni.txt', force, acceleration, jitter_s=20e-6)
    recording = read_lab_file(path, {})
    assert recording.sample_rate_hz == pytest.approx(RATE_HZ, rel=1e-4)
    assert recording.response_quantity == 'acceleration'
    np.testing.assert_allclose(recording.response, acceleration * 9.80665, atol=1e-5)
    np.testing.assert_allclose(recording.force_n, force, atol=1e-5)
    report = '\n'.join(recording.report)
    assert 'decimal comma' in report and 'date-time stamps' in report and 'utf-8-sig' in report
    # Uniform jitter of +-20 us: 11.5 us rms on each stamp, its steps scatter by sqrt(2) more.
    rms_us = float(report.split('jitter ')[1].split(' us rms')[0])
    assert 12 < rms_us < 20


def test_stamps_going_backwards_are_refused_naming_the_row(tmp_path):
    force, acceleration = signals()
    path = ni_export(tmp_path / 'ni.txt', force, acceleration, swap_at=1000)
    with pytest.raises(BadInputError, match=r'goes backwards at data row 1002'):
        read_lab_file(path, {})


def test_an_ni_export_is_analysed_and_its_hammer_listed(tmp_path, capsys):
    force, acceleration = signals()
    path = ni_export(tmp_path / 'ni.txt', force, acceleration, jitter_s=5e-6)
    assert main(['analyze', str(path), '--continuous', '--force-only', '--json']) == 0
    assert '"time_s": 1.00' in capsys.readouterr().out
    assert main(['analyze', str(path), '--band-limit-hz', '400']) == 0
    out, err = capsys.readouterr()
    assert 'ni.txt' in out and 'jitter' in err
