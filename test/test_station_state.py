"""The station's data without ROS or a browser: session metadata checked field by
field, traces decimated without losing their peaks, progress and advice per level, decisions
shown on their hit."""

import json
import math
import types

import numpy as np
import pytest

from fmm_ros.core.signal.judging import Decision
from fmm_ros.errors import BadInputError
from fmm_ros.io import session_info
from fmm_ros.station.server import event_text
from fmm_ros.station.state import Level, StationState, envelope


def test_session_metadata_is_checked_and_normalised():
    info = session_info.validated(
        {
            'operator_name': ' kb ',
            'lubricant': 'ISO VG 32',
            'normal_load_n': '6.67',
            'temperature_c': 21.5,
            'relative_humidity_percent': '',
            'notes': 'new counterface\nrun-in 10 min',
        }
    )
    assert info['operator_name'] == 'kb' and info['normal_load_n'] == 6.67
    assert math.isnan(info['relative_humidity_percent']) and info['pin'] == ''
    assert session_info.from_json(session_info.to_json(info)) == pytest.approx(info, nan_ok=True)
    assert ('normal load', '6.67 N') in session_info.describe(info)
    assert json.loads(session_info.to_json(info))['relative_humidity_percent'] is None


@pytest.mark.parametrize(
    ('values', 'words'),
    [
        ({'operator_name': 'x' * 65}, 'operator is 65 characters long (at most 64)'),
        ({'notes': 'n' * 2001}, 'notes is 2001 characters long (at most 2000)'),
        ({'pin': 'PTFE\x1b[31m'}, 'pin holds control characters'),
        ({'normal_load_n': 'heavy'}, "normal load 'heavy' is not a number [N]"),
        ({'relative_humidity_percent': 140}, 'relative humidity 140 % is outside [0, 100]'),
        ({'temperature_c': True}, 'temperature True is not a number'),
        ({'colour': 'red'}, "unknown field 'colour'"),
    ],
)
def test_metadata_that_cannot_be_stored_as_entered_is_refused(values, words):
    with pytest.raises(BadInputError, match='session metadata refused') as error:
        session_info.validated(values)
    assert words in str(error.value)


def test_the_envelope_keeps_every_peak_and_every_gap():
    values = np.zeros(100_000)
    values[31_337] = 1234.0
    values[70_000:71_000] = np.nan
    positions, shown = envelope(values, 600)
    assert shown.size == 1200 and positions.size == 1200
    assert np.nanmax(shown) == 1234.0
    assert np.isnan(shown).sum() >= 2  # whole buckets of missing samples stay missing
    short = np.arange(10.0)
    assert np.array_equal(envelope(short, 600)[1], short)


def result(impact_id, level, peak, accepted=True):
    """An ImpactResult as the station reads it."""
    return types.SimpleNamespace(
        impact_id=impact_id,
        trigger_sample_index=1000 * impact_id,
        level=level,
        accepted=accepted,
        flags=[] if accepted else ['clipped'],
        peak_force_n=peak,
        impulse_n_s=1.0,
        natural_frequency_hz=2.2,
        frequency_hz=[0.0, 1.0],
        mobility_real=[0.0, 1e-3],
        mobility_imag=[0.0, -1e-3],
    )


def test_progress_counts_what_a_fit_takes_and_advises_the_next_hit():
    events = []
    state = StationState(
        [Level('low', 450.0, 50.0), Level('high', 1450.0, 50.0)],
        target_hits=2,
        mode='manual',
        emit=lambda name, payload: events.append((name, payload)),
    )
    state.on_impact(result(0, 'low', 455.0))
    assert state.snapshot()['progress']['advice'] == 'on target'
    state.on_impact(result(1, 'low', 530.0, accepted=False))
    progress = state.snapshot()['progress']
    assert progress['advice'] == 'softer' and progress['aim'] == 'low'
    assert [lv['taken'] for lv in progress['levels']] == [1, 0]
    state.on_decision(Decision(1, 'accept', 'alice', 'looked fine'))
    progress = state.snapshot()['progress']
    assert [lv['taken'] for lv in progress['levels']] == [2, 0] and progress['aim'] == 'high'
    assert progress['advice'] == 'harder'  # 530 N is far below the high level
    row = state.snapshot()['hits'][1]
    assert row['taken'] and row['decision']['decided_by'] == 'alice'
    names = [name for name, _ in events]
    assert names.count('hit') == 3 and names.count('figure') == 2 and 'progress' in names
    # Every event is plain JSON the browser parses (event_text refuses NaN).
    for name, payload in events:
        assert json.loads(event_text(name, payload).split('data: ', 1)[1]) == payload
