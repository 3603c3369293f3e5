"""The per-impact CSV format: round trip and every kind of bad file refused by name."""

import numpy as np
import pytest

from fmm_ros.core.signal.records import ImpactRecord, read_impact_csv, write_impact_csv
from fmm_ros.errors import BadInputError


def test_round_trip_keeps_samples_and_rate(tmp_path):
    rng = np.random.default_rng(0)
    force, velocity = rng.normal(size=500), rng.normal(size=500)
    write_impact_csv(tmp_path / 'a.csv', force, velocity, 10_000.0)
    record = read_impact_csv(tmp_path / 'a.csv')
    assert record.force_n.tobytes() == force.tobytes()
    assert record.velocity_m_s.tobytes() == velocity.tobytes()
    assert record.sample_rate_hz == pytest.approx(10_000.0, rel=1e-12)
    assert record.source.endswith('a.csv') and record.window_samples == 500


def test_columns_in_any_order_with_extras(tmp_path):
    path = tmp_path / 'b.csv'
    path.write_text('velocity_m_s,note,time_s,force_n\n0.1,x,0.0,5\n0.2,y,0.001,6\n0.3,z,0.002,7\n')
    record = read_impact_csv(path)
    assert record.force_n.tolist() == [5, 6, 7] and record.velocity_m_s.tolist() == [0.1, 0.2, 0.3]
    assert record.sample_rate_hz == pytest.approx(1000.0)


@pytest.mark.parametrize(
    'text, message',
    [
        ('', 'empty file'),
        ('time_s,force_n\n0,1\n0.001,2\n', 'missing column.*velocity_m_s'),
        (
            'time_s,force_n,velocity_m_s\n0,1,0\n0.001,2,0\n0.003,3,0\n0.004,4,0\n',
            'non-uniform time step: 0.002 s between samples 1 and 2',
        ),
        ('time_s,force_n,velocity_m_s\n0,1,0\n0.001,nan,0\n0.002,3,0\n', 'force_n is not finite'),
        ('time_s,force_n,velocity_m_s\n0,1,0\n0.001,oops,0\n', 'b.csv'),
        ('time_s,force_n,velocity_m_s\n0,1,0\n', 'at least 2 samples'),
        ('time_s,force_n,velocity_m_s\n0.002,1,0\n0.001,1,0\n0.000,1,0\n', 'goes backwards'),
    ],
)
def test_bad_files_are_refused_naming_the_problem(tmp_path, text, message):
    path = tmp_path / 'b.csv'
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        read_impact_csv(path)


def test_record_checks_its_arrays():
    with pytest.raises(BadInputError, match='sample-aligned'):
        ImpactRecord(np.zeros(10), np.zeros(9), 1000.0)
    with pytest.raises(ValueError, match='shorter than the record'):
        ImpactRecord(np.zeros(10), np.zeros(10), 1000.0, window_samples=5)
    with pytest.raises(ValueError, match='positive'):
        ImpactRecord(np.zeros(10), np.zeros(10), 0.0)
    with pytest.raises(ValueError, match='outside the record'):
        ImpactRecord(
            np.zeros(10),
            np.zeros(10),
            1000.0,
            record_start_sample_index=100,
            trigger_sample_index=110,
        )
