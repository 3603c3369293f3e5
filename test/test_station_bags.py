"""What the station records, read back: a bag's decisions are honoured by replay's
selection (found by trigger sample), its session metadata reaches the session result and a
campaign's session table made from bags."""

import math
import types

import pytest

from fmm_ros.campaign.table import read_campaign_table
from fmm_ros.constants import DECISIONS_TOPIC, SESSION_INFO_TOPIC
from fmm_ros.core.signal.capture import CaptureConfig, capture_impacts
from fmm_ros.core.signal.judging import Decision
from fmm_ros.io import session_info
from fmm_ros.io.bags import BagWriter, new_message
from fmm_ros.io.bags.definitions import IMPACT_DECISION, SESSION_INFO
from fmm_ros.io.session_info import SESSION_KEY
from fmm_ros.report.html import Page
from fmm_ros.report.session import station_header
from fmm_ros.sim.session import simulated_session
from fmm_ros.workflows.inputs import InputOptions
from fmm_ros.workflows.session import SessionOptions, process_session

pytestmark = pytest.mark.slow

CAPTURE = CaptureConfig(window_s=5.0)
OPTIONS = SessionOptions(inputs=InputOptions(capture=CAPTURE), fit=False)


def stamp(store, ns):
    return new_message(
        store,
        'std_msgs/msg/Header',
        stamp=new_message(
            store, 'builtin_interfaces/msg/Time', sec=ns // 10**9, nanosec=ns % 10**9
        ),
    )


def decision(store, impact_id, trigger, verdict, who, reason=''):
    return new_message(
        store,
        IMPACT_DECISION,
        header=stamp(store, 10**9),
        impact_id=impact_id,
        trigger_sample_index=trigger,
        verdict=verdict,
        decided_by=who,
        reason=reason,
        mode='manual',
    )


def write_bag(path, session, *, decisions=(), info=None, in_metadata=True):
    """A recorded session with the station's topics, as the recorder writes it."""
    with BagWriter(path) as writer:
        writer.write_signals(session.force_n, session.velocity_m_s, session.sample_rate_hz)
        store = writer.typestore
        writer.add_topic('/' + DECISIONS_TOPIC, IMPACT_DECISION)
        for k, args in enumerate(decisions):
            writer.write_message('/' + DECISIONS_TOPIC, decision(store, *args), 10**9 + k)
        if info is not None:
            writer.add_topic('/' + SESSION_INFO_TOPIC, SESSION_INFO)
            writer.write_message(
                '/' + SESSION_INFO_TOPIC,
                new_message(store, SESSION_INFO, header=stamp(store, 10**9), **info),
                2 * 10**9,
            )
            if in_metadata:
                writer.set_custom_data(SESSION_KEY, session_info.to_json(info))
    return path


INFO = session_info.validated(
    {'operator_name': 'kb', 'lubricant': 'ISO VG 32', 'normal_load_n': 6.5, 'notes': 'run-in'}
)


@pytest.fixture(scope='module')
def session():
    return simulated_session(1, spacing_s=6.0, seed=3)


def test_replay_honours_the_recorded_decisions_by_trigger_sample(session, tmp_path):
    triggers = [
        record.trigger_sample_index
        for record in capture_impacts(
            session.force_n, session.velocity_m_s, session.sample_rate_hz, CAPTURE
        )
    ]
    bag = write_bag(
        tmp_path / 'judged',
        session,
        decisions=[
            # Live ids need not be replay's: the trigger sample finds the hit.
            (40, triggers[0], 'reject', 'alice', 'double tap'),
            (41, triggers[1], 'reject', 'alice'),
            (41, triggers[1], 'accept', 'bob', 'second look'),
            (99, 12, 'reject', 'alice'),
        ],
        info=INFO,
    )
    result = process_session([bag], OPTIONS)
    first, second = (impact.impact_id for impact in result.summary.impacts[:2])
    assert first not in result.selection.chosen and second in result.selection.chosen
    assert [d.impact_id for d in result.selection.judged] == [first, second]
    assert result.selection.judged[0].reason == 'double tap'
    # The level averages take what the fit takes: hit 0 was the only one of the lowest level.
    assert [level.level for level in result.summary.levels] == ['level_2', 'level_3']
    assert result.summary.impacts[0].accepted  # its flags' verdict is still reported
    assert len(result.records) == 3
    assert any('trigger sample 12' in problem for problem in result.problems)
    assert result.session_info[str(bag)]['operator_name'] == 'kb'


def test_session_metadata_comes_from_the_metadata_or_a_crashed_bags_messages(session, tmp_path):
    crashed = write_bag(tmp_path / 'crashed', session, info=INFO, in_metadata=False)
    result = process_session([crashed], OPTIONS)
    assert result.session_info[str(crashed)]['lubricant'] == 'ISO VG 32'


def test_a_campaign_table_made_from_bags_takes_their_conditions(session, tmp_path):
    folder = tmp_path / 'campaign'
    folder.mkdir()
    write_bag(folder / 'a1', session, info=INFO)
    write_bag(folder / 'b1', session)
    table = read_campaign_table(folder)
    assert [s.session_id for s in table.sessions] == ['a1', 'b1']
    first, second = table.sessions
    assert first.conditions['lubricant'] == 'ISO VG 32'
    assert first.spec.rig.normal_force_n == 6.5  # the load entered is the load fitted with
    assert first.notes == 'run-in'
    assert second.conditions['lubricant'] is None
    assert not math.isclose(second.spec.rig.normal_force_n, 6.5)


def test_the_report_header_shows_the_metadata_and_the_decisions_escaped(tmp_path):
    """What the station recorded heads the report; text typed by the operator is shown as text."""
    info = session_info.validated(
        {'operator_name': '<b>kb</b>', 'lubricant': 'ISO VG 32', 'temperature_c': 21.5}
    )
    judged = (Decision(2, 'reject', 'kb', '<script>alert(1)</script>'),)
    session = types.SimpleNamespace(
        session_info={'/data/bag_a': info}, selection=types.SimpleNamespace(judged=judged)
    )
    page = Page(tmp_path, 'session')
    station_header(page, session)
    text = page.write().read_text()
    assert 'Session metadata of bag_a' in text and 'ISO VG 32' in text and '21.5 °C' in text
    assert '&lt;b&gt;kb&lt;/b&gt;' in text and '<b>kb' not in text
    assert 'impact 2 rejected by kb (&lt;script&gt;' in text and '<script>alert' not in text
