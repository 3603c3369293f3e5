"""`fmm import`, `fmm bag-info`, `fmm export` and the progress bar."""

import csv
import io
import json

import numpy as np
import pytest
from bag_helpers import random_message

from fmm_ros.cli import main
from fmm_ros.cli.progress import progress_bar
from fmm_ros.constants import (
    FORCE,
    FORCE_TOPIC,
    FRF_TOPIC,
    IMPACTS_TOPIC,
    VELOCITY,
    VELOCITY_TOPIC,
    resolve_name,
)
from fmm_ros.io.bags import FRF_SUMMARY, IMPACT_RESULT, BagWriter, fmm_typestore
from fmm_ros.io.bags.tables import table_columns

FS = 10_000.0


@pytest.fixture
def lab_csv(tmp_path):
    time_s = np.arange(12_000) / FS
    force_lbf = np.sin(2 * np.pi * time_s)
    velocity_mm_s = np.cos(2 * np.pi * time_s)
    path = tmp_path / 'trial.csv'
    np.savetxt(
        path,
        np.column_stack([time_s, force_lbf, velocity_mm_s]),
        delimiter=',',
        header='Time,Hammer,Vibrometer',
        comments='',
        fmt='%.6f',
    )
    return path


def test_import_lists_channels_then_writes_a_bag_that_bag_info_describes(tmp_path, lab_csv, capsys):
    assert main(['import', str(lab_csv), '--list']) == 0
    assert capsys.readouterr().out.split('\n')[1:4] == ['  Time', '  Hammer', '  Vibrometer']

    mapping = tmp_path / 'map.yaml'
    mapping.write_text(
        'force: {name: Hammer, unit: lbf}\n'
        'velocity: {name: Vibrometer, unit: m/s}\n'
        'time: {name: Time, unit: s}\n'
    )
    bag = tmp_path / 'bag'
    # The flag overrides the file's velocity unit.
    assert (
        main(
            ['import', str(lab_csv), '-o', str(bag), '-m', str(mapping), '--velocity-unit', 'mm/s']
        )
        == 0
    )
    out, err = capsys.readouterr()
    assert "velocity: 'Vibrometer' [mm/s] × 0.001 -> m/s" in out
    assert 'sample rate: 10000 Hz (time channel' in out
    assert err == ''  # no progress bar when stderr is not a terminal

    assert main(['bag-info', str(bag)]) == 0
    out = capsys.readouterr().out
    assert 'channel /fmm/force: force [N] at 10000 Hz, 12000 samples (1.200 s) in 24 ' in out
    assert out.count('gaps: none') == 2

    assert main(['bag-info', str(bag), '--json']) == 0
    info = json.loads(capsys.readouterr().out)
    assert info['topics'][resolve_name(FORCE_TOPIC)]['count'] == 24
    assert info['channels'][resolve_name(VELOCITY_TOPIC)]['sample_rate_hz'] == [FS]
    assert info['problems'] == []


def test_bag_info_reports_gaps_clipping_and_a_crashed_recording(tmp_path, capsys):
    bag = tmp_path / 'bag'
    writer = BagWriter(bag, time_origin_ns=0)
    writer.open()
    samples = np.linspace(-1, 1, 500)
    for index in (0, 500, 1500, 2000):  # the batch at 1000 was dropped on both channels
        writer.write_sample_batch(
            FORCE_TOPIC,
            samples * 600,
            quantity=FORCE,
            sample_rate_hz=FS,
            first_sample_index=index,
            full_scale=500,
        )
        writer.write_sample_batch(
            VELOCITY_TOPIC, samples, quantity=VELOCITY, sample_rate_hz=FS, first_sample_index=index
        )
    writer.flush()  # and the process dies here: no close, no metadata.yaml
    assert main(['bag-info', str(bag)]) == 1
    out, err = capsys.readouterr()
    assert 'gaps: 1 (500 samples missing): 500 at 1000' in out
    assert 'clipped samples: 336' in out  # |600 x| >= 500 for 4 x 84 samples
    assert 'recovered by scanning' in out
    assert 'fmm bag-info: warning: the recording was not closed' in err
    writer.close()


def test_export_writes_impact_and_level_tables(tmp_path, capsys):
    store = fmm_typestore()
    rng = np.random.default_rng(5)
    impacts = [random_message(store, IMPACT_RESULT, rng) for _ in range(2)]
    for impact in impacts:  # an FRF: every array over the same frequency axis
        for name in table_columns(IMPACT_RESULT)[1]:
            setattr(impact, name, rng.normal(size=17))
    summary = random_message(store, FRF_SUMMARY, rng)
    for name in table_columns(FRF_SUMMARY)[1]:
        setattr(summary, name, rng.normal(size=9))
    summary.level = 'high level'
    bag = tmp_path / 'bag'
    with BagWriter(bag, time_origin_ns=0) as writer:
        for k, impact in enumerate(impacts):
            writer.write_message(IMPACTS_TOPIC, impact, k)
        writer.write_message(FRF_TOPIC, summary, 5)
    out_dir = tmp_path / 'csv'
    assert main(['export', str(bag), '-o', str(out_dir)]) == 0
    assert '2 impacts, 1 levels: wrote 5 files' in capsys.readouterr().out

    with (out_dir / 'impacts.csv').open() as stream:
        rows = list(csv.DictReader(stream))
    assert [int(row['impact_id']) for row in rows] == [i.impact_id for i in impacts]
    assert float(rows[1]['impulse_n_s']) == impacts[1].impulse_n_s
    assert rows[0]['flags'] == '|'.join(impacts[0].flags)
    stamp = impacts[0].header.stamp
    assert int(rows[0]['stamp_ns']) == stamp.sec * 10**9 + stamp.nanosec
    assert 'mobility_real' not in rows[0]  # arrays go to the per-impact FRF files

    impact_id = impacts[0].impact_id
    frf = np.genfromtxt(out_dir / f'impact_{impact_id}.csv', delimiter=',', names=True)
    np.testing.assert_array_equal(frf['frequency_hz'], impacts[0].frequency_hz)
    np.testing.assert_array_equal(
        frf[f'impact_{impact_id}_receptance_imag'], impacts[0].receptance_imag
    )
    level = np.genfromtxt(out_dir / 'level_high_level.csv', delimiter=',', names=True)
    np.testing.assert_array_equal(level['high_level_coherence'], summary.coherence)
    np.testing.assert_array_equal(level['high_level_h2_mobility_real'], summary.h2_mobility_real)
    with (out_dir / 'levels.csv').open() as stream:
        (row,) = list(csv.DictReader(stream))
    assert row['impact_ids'] == '|'.join(str(i) for i in summary.impact_ids)

    # The same FRFs as UFF 58, read back with pyuff (the signal core's exporter writes them).
    import pyuff

    assert main(['export', str(bag), '-o', str(tmp_path / 'uff'), '--frf-format', 'uff']) == 0
    sets = pyuff.UFF(str(tmp_path / 'uff' / 'level_high_level.uff')).read_sets()
    coherence = next(s for s in sets if s.get('id1') == 'high level coherence')
    np.testing.assert_allclose(coherence['data'], summary.coherence, rtol=1e-10)  # 12 digits


def test_export_of_a_bag_without_results_names_what_it_has(tmp_path, capsys):
    bag = tmp_path / 'bag'
    with BagWriter(bag, time_origin_ns=0) as writer:
        writer.write_signals(np.zeros(500), np.zeros(500), FS)
    assert main(['export', str(bag), '-o', str(tmp_path / 'csv')]) == 2
    err = capsys.readouterr().err
    assert 'has no topic /fmm/impacts; it has: /fmm/force' in err


class Terminal(io.StringIO):
    """A stream that says it is a terminal."""

    def isatty(self) -> bool:
        return True


def test_progress_bar_only_on_a_terminal_and_never_when_quiet():
    for stream, quiet, shown in (
        (Terminal(), False, True),
        (Terminal(), True, False),
        (io.StringIO(), False, False),
    ):
        with progress_bar(1000, desc='reading', unit='msg', quiet=quiet, stream=stream) as bar:
            bar.update(1000)
        assert ('reading' in stream.getvalue()) == shown, (quiet, type(stream))


@pytest.mark.slow
def test_analyze_names_a_bag_s_levels_as_its_analyzer_did(tmp_path, capsys):
    """bag-info and export show the recorded names (low, medium, high): so does analyze."""
    from fmm_ros.constants import PAPER_LEVELS
    from fmm_ros.sim.session import simulated_session

    session = simulated_session(1, spacing_s=8.0, seed=5)
    bag, store = tmp_path / 'bag', fmm_typestore()
    with BagWriter(bag) as writer:
        writer.write_signals(session.force_n, session.velocity_m_s, session.sample_rate_hz)
        for number, level in enumerate(PAPER_LEVELS):
            summary = random_message(store, FRF_SUMMARY, np.random.default_rng(number))
            summary.level, summary.nominal_peak_force_n = level.name, level.peak_force_n
            writer.write_message(FRF_TOPIC, summary, log_time_ns=number + 1)
    assert main(['bag-info', str(bag), '--json']) == 0
    recorded = set(json.loads(capsys.readouterr().out)['frf_levels'])
    assert recorded == {'low', 'medium', 'high'}
    assert main(['analyze', str(bag), '--window-s', '7', '--json']) == 0
    analysed = json.loads(capsys.readouterr().out)
    assert [level['name'] for level in analysed['levels']] == ['low', 'medium', 'high']
    assert main(['analyze', str(bag), '--window-s', '7', '--level', 'a=450', '--json']) == 0
    assert [level['name'] for level in json.loads(capsys.readouterr().out)['levels']] == ['a']
