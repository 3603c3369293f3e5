"""FRF export: UFF 58 read back by pyuff, CSV and JSON read back, and refusals."""

import json

import numpy as np
import pytest
import pyuff

from fmm_ros.core.signal.analysis import AnalysisConfig, ImpactAnalysis, analyze_impact, summarize
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.io.frf_files import (
    FrfCurve,
    impact_curves,
    level_curves,
    write_frf_csv,
    write_frf_json,
    write_frfs,
    write_uff58,
)

AXIS = np.arange(3301) / 33.0  # 0 .. 100 Hz by 1/33 Hz, the paper's grid
MOBILITY = (1 + AXIS) * np.exp(1j * AXIS)
COHERENCE = np.cos(AXIS) ** 2
CURVES = [
    FrfCurve('medium mean mobility', 'mobility', AXIS, MOBILITY),
    FrfCurve('medium mean receptance', 'receptance', AXIS, MOBILITY / 3),
    FrfCurve('medium coherence', 'coherence', AXIS, COHERENCE),
]


def test_uff58_round_trip_through_pyuff(tmp_path):
    path = tmp_path / 'frf.uff'
    write_uff58(path, CURVES)
    uff = pyuff.UFF(str(path))
    assert uff.get_set_types().tolist() == [164, 58, 58, 58]
    units, mobility, receptance, coherence = uff.read_sets()
    assert units['units_code'] == 1
    assert mobility['id1'].strip() == 'medium mean mobility'
    assert (
        mobility['func_type'],
        mobility['ordinate_spec_data_type'],
        mobility['orddenom_spec_data_type'],
    ) == (4, 11, 13)
    assert receptance['ordinate_spec_data_type'] == 8
    assert coherence['func_type'] == 6 and not np.iscomplexobj(coherence['data'])
    np.testing.assert_allclose(mobility['data'], MOBILITY, rtol=1e-10)
    np.testing.assert_allclose(coherence['data'], COHERENCE, rtol=1e-10, atol=1e-15)
    # UFF stores the frequency step with 6 digits: 1e-6 relative over the axis.
    np.testing.assert_allclose(mobility['x'], AXIS, rtol=1e-5, atol=1e-9)


def test_csv_round_trip(tmp_path):
    path = tmp_path / 'frf.csv'
    write_frf_csv(path, CURVES)
    header = path.read_text().splitlines()[0].split(',')
    assert header == [
        'frequency_hz',
        'medium_mean_mobility_real',
        'medium_mean_mobility_imag',
        'medium_mean_receptance_real',
        'medium_mean_receptance_imag',
        'medium_coherence',
    ]
    data = np.loadtxt(path, delimiter=',', skiprows=1)
    np.testing.assert_array_equal(data[:, 0], AXIS)
    np.testing.assert_array_equal(data[:, 1] + 1j * data[:, 2], MOBILITY)
    np.testing.assert_array_equal(data[:, 5], COHERENCE)


def test_json_round_trip_with_nan_as_null(tmp_path):
    path = tmp_path / 'frf.json'
    values = MOBILITY.copy()
    values[0] = complex(np.nan, np.nan)
    write_frf_json(path, [FrfCurve('x', 'mobility', AXIS, values)])
    (curve,) = json.loads(path.read_text())['curves']
    assert (curve['name'], curve['quantity'], curve['unit']) == ('x', 'mobility', 'm/(N*s)')
    assert curve['real'][0] is None and curve['imag'][0] is None
    np.testing.assert_array_equal(
        np.array(curve['real'][1:]) + 1j * np.array(curve['imag'][1:]), MOBILITY[1:]
    )


def test_format_from_suffix_and_refusals(tmp_path):
    for name in ('a.UFF', 'a.unv', 'a.csv', 'a.json'):
        write_frfs(tmp_path / name, CURVES)
        assert (tmp_path / name).stat().st_size > 0
    with pytest.raises(ValueError, match='unknown export format'):
        write_frfs(tmp_path / 'a.xlsx', CURVES)
    with pytest.raises(ValueError, match='nothing to export'):
        write_frfs(tmp_path / 'b.csv', [])
    with pytest.raises(ValueError, match='one frequency axis'):
        write_frf_csv(
            tmp_path / 'c.csv', [CURVES[0], FrfCurve('y', 'mobility', AXIS[:10], MOBILITY[:10])]
        )
    with pytest.raises(ValueError, match='unknown quantity'):
        FrfCurve('z', 'compliance', AXIS, MOBILITY)


def test_curves_from_a_summary_and_from_impacts():
    rate, n = 1000.0, 4000
    force = np.zeros(n)
    force[100:105] = [0, 300, 450, 300, 0]
    velocity = np.zeros(n)
    velocity[103:900] = 0.01 * np.sin(np.arange(797) / 50) * np.exp(-np.arange(797) / 100)
    results: list[ImpactAnalysis] = [
        analyze_impact(ImpactRecord(force * scale, velocity * scale, rate), impact_id=i)
        for i, scale in enumerate((1.0, 1.05))
    ]
    summary = summarize(results, AnalysisConfig())
    curves = level_curves(summary)
    assert [c.name for c in curves] == [
        'level_1 mean mobility',
        'level_1 mean receptance',
        'level_1 H1 mobility',
        'level_1 H2 mobility',
        'level_1 coherence',
    ]
    np.testing.assert_array_equal(curves[2].values, summary.levels[0].h1_mobility)
    assert [c.name for c in impact_curves(summary.impacts)] == [
        'impact 0 level_1 mobility',
        'impact 1 level_1 mobility',
    ]
