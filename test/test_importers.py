"""Importers: lab files made with their own libraries become SI session bags."""

import zipfile

import h5py
import numpy as np
import pytest
import scipy.io
from nptdms import ChannelObject, GroupObject, TdmsWriter

from fmm_ros.io.bags import BagReader
from fmm_ros.io.labfiles import (
    ChannelMapping,
    ImportMapping,
    import_to_bag,
    load_mapping,
    open_lab_file,
    read_lab_file,
)

FS = 10_000.0
N = 2_345  # not a whole number of batches
LBF = 4.4482216152605


def raw_channels(n: int = N, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.normal(0, 100, n), rng.normal(0, 5, n)


def bag_arrays(bag):
    with BagReader(bag) as reader:
        batches = list(reader.batches())
    assert [b.first_sample_index for b in batches] == list(range(0, len(batches) * 500, 500))
    rates = {b.sample_rate_hz for b in batches}
    return (
        np.concatenate([b.force for b in batches]),
        np.concatenate([b.velocity for b in batches]),
        rates.pop(),
    )


def test_csv_with_header_units_and_a_time_column(tmp_path):
    force_lbf, velocity_mm_s = raw_channels()
    time_s = np.arange(N) / FS
    path = tmp_path / 'hit.csv'
    np.savetxt(
        path,
        np.column_stack([time_s, force_lbf, velocity_mm_s]),
        delimiter=',',
        header='Time [s],Hammer [lbf],Vibrometer [mm/s]',
        comments='',
    )
    mapping = ImportMapping.from_dict(
        {
            'force': {'name': 'Hammer [lbf]', 'unit': 'lbf'},
            'velocity': {'name': 'Vibrometer [mm/s]', 'unit': 'mm/s'},
            'time': {'name': 'Time [s]', 'unit': 's'},
        }
    )
    summary = import_to_bag([path], tmp_path / 'bag', mapping)
    assert summary.samples == N and summary.sample_rate_hz == pytest.approx(FS)
    force, velocity, rate = bag_arrays(tmp_path / 'bag')
    np.testing.assert_allclose(force, force_lbf * LBF, rtol=1e-15)
    np.testing.assert_allclose(velocity, velocity_mm_s * 1e-3, rtol=1e-15)
    assert rate == pytest.approx(FS)
    assert any('lbf' in line and '-> N' in line for line in summary.report)


def test_headerless_whitespace_text_is_addressed_by_column_number(tmp_path):
    force_n, velocity = raw_channels()
    path = tmp_path / 'hit.txt'
    np.savetxt(path, np.column_stack([velocity, force_n]))
    lab = open_lab_file(path)
    assert lab.names() == ['0', '1']
    mapping = ImportMapping(ChannelMapping('1', 'N'), ChannelMapping('0', 'm/s'), FS)
    recording = read_lab_file(path, mapping)
    np.testing.assert_allclose(recording.force_n, force_n, rtol=1e-15)


def test_npz_with_the_rate_in_a_variable_and_a_volt_channel_with_a_stated_scale(tmp_path):
    force_n, velocity_v = raw_channels()
    path = tmp_path / 'hit.npz'
    np.savez(path, F=force_n, V=velocity_v[:, None], fs=np.array(FS))
    mapping = ImportMapping.from_dict(
        {
            'force': {'name': 'F', 'unit': 'N'},
            'velocity': {'name': 'V', 'unit': 'V', 'scale': 0.125, 'full_scale': 10},
            'sample_rate_hz': 'fs',
        }
    )
    import_to_bag([path], tmp_path / 'bag', mapping, storage='sqlite3')
    force, velocity, rate = bag_arrays(tmp_path / 'bag')
    np.testing.assert_array_equal(force, force_n)
    np.testing.assert_allclose(velocity, velocity_v * 0.125, rtol=1e-15)
    assert rate == FS
    with BagReader(tmp_path / 'bag') as reader:
        assert next(reader.batches()).full_scale_velocity == pytest.approx(1.25)


def test_matlab_v5_struct_fields(tmp_path):
    force_kn, velocity_in_s = raw_channels()
    path = tmp_path / 'hit.mat'
    scipy.io.savemat(path, {'data': {'force': force_kn[:, None], 'vel': velocity_in_s}, 'Fs': FS})
    lab = open_lab_file(path)
    assert lab.format == 'MATLAB' and {'data.force', 'data.vel', 'Fs'} <= set(lab.names())
    mapping = ImportMapping.from_dict(
        {
            'force': {'name': 'data.force', 'unit': 'kN'},
            'velocity': {'name': 'data.vel', 'unit': 'in/s'},
            'sample_rate_hz': 'Fs',
        }
    )
    import_to_bag([path], tmp_path / 'bag', mapping)
    force, velocity, _ = bag_arrays(tmp_path / 'bag')
    np.testing.assert_allclose(force, force_kn * 1e3, rtol=1e-15)
    np.testing.assert_allclose(velocity, velocity_in_s * 0.0254, rtol=1e-15)


def test_matlab_v73_is_read_through_hdf5(tmp_path):
    force_n, velocity = raw_channels()
    path = tmp_path / 'hit73.mat'
    # What MATLAB's save -v7.3 writes: a 512-byte user block, column vectors stored
    # transposed (1 x N), scalars as 1 x 1, and a #refs# group for cells and strings.
    with h5py.File(path, 'w', userblock_size=512) as hdf:
        hdf['force'] = force_n[None, :]
        hdf.create_group('rig')['velocity'] = velocity[None, :]
        hdf['fs'] = np.array([[FS]])
        hdf.create_group('#refs#')['a'] = np.zeros(3)
    with path.open('r+b') as stream:
        stream.write(b'MATLAB 7.3 MAT-file, Platform: GLNXA64'.ljust(128))
    lab = open_lab_file(path)
    assert lab.format == 'MATLAB v7.3'
    assert sorted(lab.names()) == ['force', 'fs', 'rig.velocity']
    mapping = ImportMapping.from_dict(
        {
            'force': {'name': 'force', 'unit': 'N'},
            'velocity': {'name': 'rig.velocity', 'unit': 'm/s'},
            'sample_rate_hz': 'fs',
        }
    )
    import_to_bag([path], tmp_path / 'bag', mapping)
    force, velocity_read, rate = bag_arrays(tmp_path / 'bag')
    np.testing.assert_array_equal(force, force_n)
    np.testing.assert_array_equal(velocity_read, velocity)
    assert rate == FS


def test_tdms_units_rate_and_start_time_come_from_the_file(tmp_path):
    force_n, velocity_mm_s = raw_channels()
    start = np.datetime64('2019-03-14T10:20:30.000000', 'us')
    path = tmp_path / 'hit.tdms'
    common = {'wf_increment': 1 / FS, 'wf_start_time': start}
    with TdmsWriter(path) as writer:
        writer.write_segment(
            [
                GroupObject('Impact'),
                ChannelObject('Impact', 'Force', force_n, {**common, 'unit_string': 'N'}),
                ChannelObject(
                    'Impact', 'Velocity', velocity_mm_s, {**common, 'unit_string': 'mm/s'}
                ),
            ]
        )
    mapping = ImportMapping.from_dict({'force': 'Impact/Force', 'velocity': 'Impact/Velocity'})
    summary = import_to_bag([path], tmp_path / 'bag', mapping)
    force, velocity, rate = bag_arrays(tmp_path / 'bag')
    np.testing.assert_array_equal(force, force_n)
    np.testing.assert_allclose(velocity, velocity_mm_s * 1e-3, rtol=1e-15)
    assert rate == pytest.approx(FS, rel=1e-12)
    assert any('(from the file)' in line for line in summary.report)
    with BagReader(tmp_path / 'bag') as reader:
        first = next(reader.channel('/fmm/force'))
    assert first.stamp_ns == int(start.astype('datetime64[ns]').astype(np.int64))


def test_several_files_make_one_contiguous_session(tmp_path):
    paths = []
    for k in range(3):
        force_n, velocity = raw_channels(1000, seed=k)
        paths.append(tmp_path / f'trial{k}.npz')
        np.savez(paths[-1], F=force_n, V=velocity)
    mapping = ImportMapping(ChannelMapping('F', 'N'), ChannelMapping('V', 'm/s'), FS)
    summary = import_to_bag(paths, tmp_path / 'bag', mapping, batch_size=400)
    assert summary.samples == 3000 and summary.duration_s == pytest.approx(0.3)
    with BagReader(tmp_path / 'bag') as reader:
        batches = list(reader.batches())
    assert [b.first_sample_index for b in batches][:4] == [0, 400, 800, 1000]
    assert all(b.gap_samples == 0 for b in batches)
    expected = np.concatenate([raw_channels(1000, seed=k)[0] for k in range(3)])
    np.testing.assert_array_equal(np.concatenate([b.force for b in batches]), expected)


def test_a_yaml_mapping_file(tmp_path):
    path = tmp_path / 'map.yaml'
    path.write_text(
        'force: {name: Hammer, unit: lbf}\n'
        'velocity: {name: Vib, unit: V, scale: 0.125}\n'
        'sample_rate_hz: 10000\n'
    )
    mapping = ImportMapping.from_dict(load_mapping(path))
    assert mapping.force == ChannelMapping('Hammer', 'lbf')
    assert mapping.response.scale == 0.125 and mapping.response_quantity == 'velocity'
    assert mapping.sample_rate_hz == FS


@pytest.mark.parametrize(
    ('spec', 'message'),
    [
        ({'force': {'name': 'F', 'unit': 'V'}}, "unit 'V' is not a force unit"),
        ({'force': {'name': 'F', 'unit': 'lbf', 'scale': 4.4}}, 'unit lbf already fixes the scale'),
        ({'force': {'name': 'F'}}, 'no unit given'),
        ({'force': {'name': 'Force'}}, "has no channel 'Force'; it has: F, V, M, fs"),
        ({'force': {'name': 'M', 'unit': 'N'}}, 'has shape (10, 3); a channel must be a vector'),
        ({'velocity': {'name': 'V', 'unit': 'm/s'}, 'sample_rate_hz': None}, 'no sample rate'),
    ],
)
def test_mapping_errors_name_the_problem(tmp_path, spec, message):
    path = tmp_path / 'lab.npz'
    force, velocity = raw_channels(100)
    np.savez(path, F=force, V=velocity, M=np.zeros((10, 3)), fs=FS)
    full = {
        'force': {'name': 'F', 'unit': 'N'},
        'velocity': {'name': 'V', 'unit': 'm/s'},
        'sample_rate_hz': FS,
        **spec,
    }
    with pytest.raises(ValueError) as caught:
        read_lab_file(path, ImportMapping.from_dict(full))
    assert message in str(caught.value)


def test_inconsistent_files_are_refused(tmp_path):
    force, velocity = raw_channels(100)
    path = tmp_path / 'lab.csv'
    time_s = np.arange(100) / FS
    time_s[50:] += 0.5  # a jump: not one sample clock
    np.savetxt(
        path,
        np.column_stack([time_s, force, velocity[:100]]),
        delimiter=';',
        header='t;F;V',
        comments='',
    )
    mapping = {
        'force': {'name': 'F', 'unit': 'N'},
        'velocity': {'name': 'V', 'unit': 'm/s'},
        'time': {'name': 't', 'unit': 's'},
    }
    with pytest.raises(ValueError, match='non-uniform time step'):
        read_lab_file(path, ImportMapping.from_dict(mapping))
    np.savetxt(
        path,
        np.column_stack([np.arange(100) / FS, force, velocity]),
        delimiter=';',
        header='t;F;V',
        comments='',
    )
    with pytest.raises(ValueError, match='disagrees with time channel'):
        read_lab_file(path, ImportMapping.from_dict({**mapping, 'sample_rate_hz': 5000}))
    np.savez(tmp_path / 'short.npz', F=force, V=velocity[:99])
    with pytest.raises(ValueError, match='has 100 samples but velocity .* has 99'):
        read_lab_file(
            tmp_path / 'short.npz',
            ImportMapping.from_dict({**mapping, 'time': None, 'sample_rate_hz': FS}),
        )
    with pytest.raises(ValueError, match='unknown mapping keys: rate'):
        ImportMapping.from_dict({**mapping, 'rate': 1})
    # Readers are chosen by content: an Excel workbook is a zip without NumPy arrays.
    with zipfile.ZipFile(tmp_path / 'x.xlsx', 'w') as workbook:
        workbook.writestr('xl/workbook.xml', '<workbook/>')
    with pytest.raises(ValueError, match="unknown format '.xlsx': an Excel workbook"):
        open_lab_file(tmp_path / 'x.xlsx')
