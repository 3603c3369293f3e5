"""The one input layer: analyze, fit, diagnose and report read CSV, MATLAB
v5 and v7.3, TDMS and bags alike, by content; a units row gives the units; semicolons, decimal
commas and a cp1252 header are read as written, with overrides; what cannot be read says why.

Every file holds the same samples as a reference CSV in fmm's own format, written with the
format's own library (scipy.io, h5py, nptdms, plain text), and must give the same analysis.
"""

import json

import h5py
import numpy as np
import pytest
import scipy.io
from fit_records import lab_levels
from nptdms import ChannelObject, GroupObject, TdmsWriter
from signal_records import hits

from fmm_ros.cli import main
from fmm_ros.core.signal.records import write_impact_csv
from fmm_ros.io.labfiles import open_lab_file
from fmm_ros.io.textfiles import TextFormat, read_table
from fmm_ros.workflows.inputs import InputOptions, read_inputs

RATE_HZ = 1000.0
SECONDS = 4.0
MM_S = 1e-3  # m/s per mm/s


@pytest.fixture(scope='module')
def hit():
    """A 1000 N hit on a settled linear oscillator: force [N], velocity [m/s]."""
    return hits(int(SECONDS * RATE_HZ), RATE_HZ, [(500, 1000.0)], zeta=0.3, duration_s=0.02)


@pytest.fixture(scope='module')
def reference(hit, tmp_path_factory):
    """The hit in fmm's own CSV format, and what `fmm analyze --json` says of it."""
    path = tmp_path_factory.mktemp('reference') / 'hit.csv'
    write_impact_csv(path, *hit, RATE_HZ)
    return analysis_of(path)


def analysis_of(*inputs, extra=(), capsys=None):
    """`fmm analyze --json` of the inputs: its one impact's numbers (exit status checked)."""
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(['analyze', *map(str, inputs), '--json', *extra])
    assert code == 0
    return json.loads(out.getvalue())['impacts']


def same_impact(found, reference):
    assert len(found) == len(reference) == 1
    for key in ('impulse_n_s', 'peak_force_n', 'peak_receptance_m_per_n', 'natural_frequency_hz'):
        assert found[0][key] == pytest.approx(reference[0][key], rel=1e-6), key
    assert found[0]['flags'] == reference[0]['flags']


def rows(delimiter, *columns):
    """Text rows of the hit's time and the columns, numbers at full precision."""
    table = zip(np.arange(int(SECONDS * RATE_HZ)) / RATE_HZ, *columns, strict=True)
    return [delimiter.join(f'{value:.17g}' for value in row) for row in table]


def test_a_units_row_gives_each_column_its_unit(hit, reference, tmp_path):
    """Time,Hammer,Vibrometer over s,N,mm/s: no mapping needed, mm/s converted."""
    force, velocity = hit
    path = tmp_path / 'trial.csv'
    text = '\n'.join(rows(',', force, velocity / MM_S))
    path.write_text('Time,Hammer,Vibrometer\ns,N,mm/s\n' + text + '\n')
    same_impact(analysis_of(path), reference)


def test_a_german_excel_export_is_read_as_written(hit, reference, tmp_path):
    """Semicolons, decimal commas, a cp1252 header with umlauts, a preamble line, no suffix."""
    force, velocity = hit
    path = tmp_path / 'Messung_3'
    data = '\n'.join(rows(';', force, velocity / MM_S)).replace('.', ',')
    text = 'Prüfstand FMM\nZeit;Hammerkraft;Geschwindigkeit (µm/s)\ns;N;mm/s\n' + data
    path.write_bytes(text.encode('cp1252'))
    table = read_table(path)
    assert (table.delimiter, table.decimal, table.encoding) == (';', ',', 'windows-1252')
    assert table.names == ('Zeit', 'Hammerkraft', 'Geschwindigkeit (µm/s)')
    assert table.units == ('s', 'N', 'mm/s')  # the units row wins over the header's unit
    same_impact(analysis_of(path), reference)
    # The same, every detected part stated instead.
    stated = ['--delimiter', 'semicolon', '--decimal', ',', '--encoding', 'cp1252']
    same_impact(analysis_of(path, extra=stated), reference)


def test_overrides_read_what_detection_cannot(hit, reference, tmp_path):
    """A preamble with as many cells as the data looks like a header: --skip-rows says not."""
    force, velocity = hit
    path = tmp_path / 'daq.txt'
    preamble = 'device\tNI 9234\tcDAQ1Mod1\ndate\t2024-05-01\t10:00\n'
    data = '\n'.join(rows('\t', force, velocity))
    path.write_text(preamble + 'time_s\tforce_n\tvelocity_m_s\n' + data)
    code = main(['analyze', str(path)])
    assert code == 2  # the preamble's first line was taken for the header
    same_impact(analysis_of(path, extra=['--skip-rows', '2']), reference)
    assert read_table(path, TextFormat(skip_rows=2)).names == ('time_s', 'force_n', 'velocity_m_s')


@pytest.mark.parametrize(
    ('line_end', 'separator'), [('\n', ','), ('\r\n', ';'), ('\r', '\t')], ids=['lf', 'crlf', 'cr']
)
def test_a_text_file_is_read_within_a_few_times_its_size(tmp_path, line_end, separator):
    """Untrusted or large files never take memory beyond a few times their size.

    The text, the array and a piece of lines at a time (before: a list of every line and
    two more copies of the text, 6-7 times a 10 MB file). Decimal commas with semicolons
    take the same path.
    """
    import tracemalloc

    rows = np.random.default_rng(3).normal(size=(60_000, 3))
    decimal = ',' if separator == ';' else '.'
    text = line_end.join(
        ['Time;Force;Velocity'.replace(';', separator), 's;N;m/s'.replace(';', separator)]
        + [separator.join(f'{value:.9f}'.replace('.', decimal) for value in row) for row in rows]
    )
    path = tmp_path / 'big.csv'
    path.write_text(text + line_end, encoding='utf-8', newline='')
    tracemalloc.start()
    try:
        table = read_table(path)
        values = table.values()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    np.testing.assert_allclose(values, rows, atol=1e-9)
    assert table.units == ('s', 'N', 'm/s') and table.data_line == 3
    assert peak < 3.0 * path.stat().st_size, peak / path.stat().st_size


def test_matlab_v5_and_v73_and_tdms_are_read_by_content(hit, reference, tmp_path):
    force, velocity = hit
    v5 = tmp_path / 'hit.mat'
    scipy.io.savemat(v5, {'force_n': force, 'velocity_m_s': velocity, 'sample_rate_hz': RATE_HZ})
    same_impact(analysis_of(v5), reference)
    # A struct of sensor channels in other units, named by flags; the file has no suffix.
    struct = tmp_path / 'trial_0042'
    scipy.io.savemat(
        struct, {'data': {'F': force / 1e3, 'V': velocity / MM_S}, 'Fs': RATE_HZ}, appendmat=False
    )
    flags = ['--force', 'data.F', '--force-unit', 'kN', '--velocity', 'data.V']
    flags += ['--velocity-unit', 'mm/s', '--sample-rate-hz', 'Fs']
    same_impact(analysis_of(struct, extra=flags), reference)

    v73 = tmp_path / 'hit73.mat'  # as MATLAB's save -v7.3 writes: a user block, row vectors
    with h5py.File(v73, 'w', userblock_size=512) as hdf:
        hdf['force_n'], hdf['velocity_m_s'] = force[None, :], velocity[None, :]
        hdf['sample_rate_hz'] = np.array([[RATE_HZ]])
    with v73.open('r+b') as stream:
        stream.write(b'MATLAB 7.3 MAT-file, Platform: GLNXA64'.ljust(128))
    same_impact(analysis_of(v73), reference)

    tdms = tmp_path / 'hit.tdms'  # units and rate from the file: the channels need no names
    common = {'wf_increment': 1 / RATE_HZ}
    with TdmsWriter(tdms) as writer:
        writer.write_segment(
            [
                GroupObject('Impact'),
                ChannelObject('Impact', 'Hammer', force, {**common, 'unit_string': 'N'}),
                ChannelObject('Impact', 'LDV', velocity / MM_S, {**common, 'unit_string': 'mm/s'}),
            ]
        )
    same_impact(analysis_of(tdms), reference)
    assert [type(open_lab_file(p)).__name__ for p in (v5, struct, v73, tdms)] == [
        'MatFile',
        'MatFile',
        'Mat73File',
        'TdmsFile',
    ]


def test_what_cannot_be_read_says_why_and_what_to_state(hit, tmp_path, capsys):
    force, velocity = hit
    path = tmp_path / 'hit.mat'
    scipy.io.savemat(path, {'data': {'F': force, 'V': velocity}, 'Fs': RATE_HZ})
    assert main(['analyze', str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and 'utf-8' not in err
    assert 'which channel is the force?' in err and '--force NAME' in err
    assert 'data.F' in err and 'data.V' in err  # what the file has
    two = tmp_path / 'two.csv'
    two.write_text('t,F1,F2,V\ns,N,N,m/s\n0,0,0,0\n0.001,1,1,0\n')
    assert main(['analyze', str(two)]) == 2
    assert '2 channels are in force units (F1, F2)' in capsys.readouterr().err
    (tmp_path / 'photo.png').write_bytes(b'\x89PNG\r\n\x1a\n' + bytes(range(256)) * 4)
    assert main(['analyze', str(tmp_path / 'photo.png')]) == 2
    assert "unknown format '.png'" in capsys.readouterr().err


def test_a_continuous_recording_is_cut_into_its_impacts(tmp_path):
    n = int(30 * RATE_HZ)
    peaks = [(2_000, 450.0), (12_000, 1000.0), (22_000, 1450.0)]
    force, velocity = hits(n, RATE_HZ, peaks, zeta=0.3, duration_s=0.02)
    path = tmp_path / 'session.tdms'
    common = {'wf_increment': 1 / RATE_HZ}
    with TdmsWriter(path) as writer:
        writer.write_segment(
            [
                GroupObject('Session'),
                ChannelObject('Session', 'Force', force, {**common, 'unit_string': 'N'}),
                ChannelObject('Session', 'Velocity', velocity, {**common, 'unit_string': 'm/s'}),
            ]
        )
    read = read_inputs([path], InputOptions(continuous=True))
    assert [record.source for record in read.records] == [
        'session.tdms@2001',
        'session.tdms@12001',
        'session.tdms@22001',  # a half-sine's first sample is 0
    ]
    impacts = analysis_of(path, extra=['--continuous', '--window-s', '8', '--paper-levels'])
    assert [impact['accepted'] for impact in impacts] == [True] * 3
    assert [round(impact['peak_force_n']) for impact in impacts] == [450, 1000, 1450]
    assert any('Force' in note and 'the one channel in force units' in note for note in read.notes)


@pytest.mark.slow
def test_fit_takes_matlab_and_tdms_files_as_it_takes_csv(tmp_path, capsys):
    """fmm fit (and so diagnose and report, which read through the same layer)."""
    records = lab_levels(5, mu=0.113, duration_s=8.0)
    csvs, mats = [], []
    for number, record in enumerate(records):
        csvs.append(tmp_path / f'{number}.csv')
        write_impact_csv(csvs[-1], record.force_n, record.velocity_m_s, record.sample_rate_hz)
        mats.append(tmp_path / f'{number}.mat')
        scipy.io.savemat(
            mats[-1],
            {
                'Kraft': record.force_n,
                'v_mm_s': record.velocity_m_s * 1e3,
                'fs': record.sample_rate_hz,
            },
        )
    assert main(['fit', *map(str, csvs), '--json']) == 0
    from_csv = json.loads(capsys.readouterr().out)
    flags = ['--force', 'Kraft', '--force-unit', 'N', '--velocity', 'v_mm_s']
    flags += ['--velocity-unit', 'mm/s', '--sample-rate-hz', 'fs', '--json']
    assert main(['fit', *map(str, mats), *flags]) == 0
    from_mat = json.loads(capsys.readouterr().out)
    assert from_mat['mu'] == pytest.approx(from_csv['mu'], rel=1e-9)
    assert [entry['file'] for entry in from_mat['per_file']] == [str(path) for path in mats]


def test_a_non_finite_sample_of_a_one_impact_file_is_refused_naming_it(hit, tmp_path, capsys):
    force, velocity = hit
    force = force.copy()
    force[7] = np.nan
    path = tmp_path / 'gap.mat'
    scipy.io.savemat(path, {'force_n': force, 'velocity_m_s': velocity, 'sample_rate_hz': RATE_HZ})
    assert main(['analyze', str(path)]) == 2
    assert 'force_n is not finite (nan) at data row 8' in capsys.readouterr().err


@pytest.mark.slow
def test_a_labs_continuous_tdms_session_is_fitted_to_its_true_mu(tmp_path, capsys):
    """A session as NI software saves it (one TDMS file, force in lbf and velocity in mm/s with
    their unit strings, the rate as wf_increment), made by the independent generator
    (test/worlds: continuous-time plant, anti-alias filter, hum, drift, ADC): fmm fit cuts
    it into impacts, keeps the paper-level hits and finds the world's mu."""
    from worlds import World, record_session

    session = record_session(World(), np.random.default_rng(17), hits=3, tail_s=12.0)
    path = tmp_path / 'Session 2024-05-01.tdms'
    common = {'wf_increment': 1 / session.sample_rate_hz}
    with TdmsWriter(path) as writer:
        writer.write_segment(
            [
                GroupObject('Untitled'),
                ChannelObject(
                    'Untitled',
                    'Hammer',
                    session.force_n / 4.4482216152605,
                    {**common, 'unit_string': 'lbf'},
                ),
                ChannelObject(
                    'Untitled',
                    'LDV',
                    session.velocity_m_s / MM_S,
                    {**common, 'unit_string': 'mm/s'},
                ),
            ]
        )
    flags = ['--continuous', '--window-s', '12', '--paper-levels', '--tolerance-n', '80']
    flags += ['--fit-initial-position', '--rest-velocity-m-s', '2e-3', '--json']
    assert main(['fit', str(path), *flags]) == 0
    fit = json.loads(capsys.readouterr().out)
    truth = [hit.mu for hit in session.truth.hits]
    assert len(fit['per_file']) == 3
    assert fit['mu'] == pytest.approx(np.mean(truth), rel=0.01)
