"""`fmm analyze`: JSON and text reports, exports, and bad input as one-line errors (exit 2)."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from signal_records import hits

from fmm_ros.cli import main
from fmm_ros.core.signal.analysis import analyze_impact
from fmm_ros.core.signal.capture import CaptureConfig, capture_impacts
from fmm_ros.core.signal.records import read_impact_csv, write_impact_csv

RATE_HZ = 1000.0
SECONDS = 4.0


def impact_file(path, peak_n, rate_hz=RATE_HZ, zeta=0.3, at_s=0.5, seconds=SECONDS):
    n = int(seconds * rate_hz)
    # A 20 ms pulse: 20 samples at 1 kHz, enough for the trapezoid to be within 0.2 %.
    force, velocity = hits(n, rate_hz, [(int(at_s * rate_hz), peak_n)], zeta=zeta, duration_s=0.02)
    write_impact_csv(path, force, velocity, rate_hz)
    return path


@pytest.fixture
def series(tmp_path):
    peaks = [450, 480, 1000, 1020, 1450, 1900]
    return [impact_file(tmp_path / f'hit_{i}.csv', p) for i, p in enumerate(peaks)]


def run_cli(capsys, *args):
    code = main(['analyze', *map(str, args)])
    out, err = capsys.readouterr()
    return code, out, err


def test_a_series_of_lab_files_gets_one_id_per_hit_laid_end_to_end(series, capsys):
    """Each file triggers near its own t = 0.5 s: on one session axis the ids still differ."""
    code, out, _ = run_cli(capsys, *series, '--json')
    assert code == 0
    ids = [impact['impact_id'] for impact in json.loads(out)['impacts']]
    assert len(set(ids)) == len(series)
    # file k starts on the ms after file k-1 ended (4 s each), and triggers near 500 ms into it
    file_ms = int(SECONDS * 1000) + 1
    assert all(480 <= impact_id - k * file_ms <= 520 for k, impact_id in enumerate(ids)), ids


def test_two_hits_at_one_time_of_the_session_are_refused_naming_both():
    from fmm_ros.core.signal.records import ImpactRecord
    from fmm_ros.errors import BadInputError
    from fmm_ros.workflows.session import analyse

    force, velocity = hits(4000, RATE_HZ, [(500, 800.0)], zeta=0.3, duration_s=0.02)
    first, second = (
        ImpactRecord(force, velocity, RATE_HZ, source=name, acquisition_origin_s=1.7e9)
        for name in ('first.mcap', 'second.mcap')
    )
    with pytest.raises(BadInputError, match=r'first\.mcap and second\.mcap .*impact id'):
        analyse([first, second])


def test_json_report_has_exactly_the_documented_keys(series, capsys):
    code, out, _ = run_cli(capsys, *series, '--json', '--paper-levels')
    assert code == 0
    report = json.loads(out)
    assert list(report) == ['impacts', 'levels', 'linearity']
    assert list(report['impacts'][0]) == [
        'file',
        'impact_id',
        'accepted',
        'flags',
        'impulse_n_s',
        'peak_force_n',
        'peak_receptance_m_per_n',
        'natural_frequency_hz',
        'natural_frequency_method',
        'natural_frequency_uncertainty_hz',
    ]
    assert list(report['levels'][0]) == [
        'name',
        'count',
        'mean_impulse_n_s',
        'peak_receptance_m_per_n',
    ]
    assert list(report['linearity']) == ['slope', 'intercept', 'r2']
    assert [i['file'] for i in report['impacts']] == [str(p) for p in series]
    assert [(i['accepted'], i['flags']) for i in report['impacts']] == [(True, [])] * 5 + [
        (False, ['out_of_tolerance'])
    ]
    assert [(lv['name'], lv['count']) for lv in report['levels']] == [
        ('low', 2),
        ('medium', 2),
        ('high', 1),
    ]
    first = report['impacts'][0]
    assert first['peak_force_n'] == pytest.approx(450, rel=1e-3)
    assert first['impulse_n_s'] == pytest.approx(450 * 0.02 * 2 / np.pi, rel=5e-3)
    # Receptance of a 30 %-damped mode peaks at f_n sqrt(1 - 2 zeta^2), on a 0.25 Hz grid.
    assert first['natural_frequency_hz'] == pytest.approx(2.2 * np.sqrt(1 - 2 * 0.3**2), abs=0.13)
    # A linear oscillator's peak receptance does not depend on the impulse: R^2 is undefined.
    assert report['linearity']['r2'] is None


def test_clustering_text_report_and_exports(series, capsys, tmp_path):
    uff, csv = tmp_path / 'levels.uff', tmp_path / 'levels.csv'
    code, out, _ = run_cli(capsys, *series, '-o', uff, '-o', csv)
    assert code == 0
    assert 'hit_5.csv' in out and 'level_4' in out  # 1900 N is a level of its own
    assert 'linearity:' in out
    assert uff.read_text().count('\n    58') == 4 * 9  # 4 levels x 9 curves
    header = csv.read_text().splitlines()[0].split(',')
    assert header[:2] == ['frequency_hz', 'level_1_mean_mobility_real']
    for estimator in ('h1', 'h2'):
        for form in ('accelerance', 'mobility', 'receptance'):
            assert {f'level_4_{estimator}_{form}_real', f'level_4_{estimator}_{form}_imag'} < set(
                header
            )
    assert 'level_4_coherence' in header


def test_rejection_is_configurable(tmp_path, capsys):
    ringing = impact_file(tmp_path / 'ringing.csv', 1000, zeta=0.001)
    code, out, _ = run_cli(capsys, ringing, '--json')
    assert json.loads(out)['impacts'][0]['flags'] == ['unsettled']
    assert json.loads(out)['impacts'][0]['accepted'] is False
    code, out, _ = run_cli(capsys, ringing, '--json', '--reject', 'gap,nan')
    assert json.loads(out)['impacts'][0]['accepted'] is True


@pytest.mark.slow
def test_a_file_and_a_live_capture_of_the_same_samples_agree(tmp_path):
    n = int(40 * 10_000)
    force, velocity = hits(n, 10_000.0, [(20_000, 1000.0)], zeta=0.05)
    (record,) = capture_impacts(force, velocity, 10_000.0, CaptureConfig())
    write_impact_csv(tmp_path / 'one.csv', record.force_n, record.velocity_m_s, 10_000.0)
    live = analyze_impact(record)
    from_file = analyze_impact(read_impact_csv(tmp_path / 'one.csv'))
    offset = live.trigger_sample_index - live.record_start_sample_index
    assert from_file.trigger_sample_index == offset  # the file starts at the record start
    assert from_file.flags == live.flags == ()
    assert from_file.impulse_n_s == pytest.approx(live.impulse_n_s, rel=1e-12)
    np.testing.assert_allclose(from_file.mobility, live.mobility, rtol=1e-9)


@pytest.mark.parametrize(
    'content, problem',
    [
        ('time_s,force_n\n0,0\n0.001,1\n', 'missing column(s) velocity_m_s'),
        (
            'time_s,force_n,velocity_m_s\n0,0,0\n0.001,30,0\n0.003,0,0\n0.004,0,0\n',
            'non-uniform time step',
        ),
        ('time_s,force_n,velocity_m_s\n0,0,0\n0.001,nan,0\n0.002,0,0\n', 'force_n is not finite'),
        ('time_s,force_n,velocity_m_s\n0,0,0\n0.001,1,0\n0.002,0,0\n', 'never reaches the trigger'),
    ],
)
def test_bad_input_is_one_line_naming_the_problem(tmp_path, capsys, series, content, problem):
    bad = tmp_path / 'bad.csv'
    bad.write_text(content)
    code, out, err = run_cli(capsys, series[0], bad)
    assert code == 2 and out == ''
    assert err.count('\n') == 1 and err.startswith('fmm analyze: error: ')
    assert problem in err and 'bad.csv' in err


def test_mismatched_rates_and_missing_files(tmp_path, capsys, series):
    other = impact_file(tmp_path / 'fast.csv', 450, rate_hz=4000.0)
    code, _, err = run_cli(capsys, series[0], other)
    assert code == 2 and 'mismatched sample rates' in err and 'fast.csv' in err
    code, _, err = run_cli(capsys, tmp_path / 'absent.csv')
    assert code == 2 and 'absent.csv' in err
    code, _, err = run_cli(capsys, series[0], '-o', tmp_path / 'x.xlsx')
    assert code == 2 and 'unknown export format' in err


def test_bad_options_are_refused_by_the_parser(series, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(['analyze', str(series[0]), '--level', 'low'])
    assert exit_info.value.code == 2
    assert 'NAME=FORCE_N' in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(['analyze', str(series[0]), '--reject', 'wobbly'])
    assert 'unknown flag' in capsys.readouterr().err


@pytest.mark.slow
def test_installed_command_runs(series):
    fmm = Path(sys.executable).with_name('fmm')
    result = subprocess.run(
        [str(fmm), 'analyze', str(series[0]), '--json'], capture_output=True, text=True
    )
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)['impacts'][0]['accepted'] is True
