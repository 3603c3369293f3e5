"""Judging hits: decisions overrule the flags through the one selection rule, the
running mu forgets a rejected hit exactly, bad decisions are refused with their reason."""

import math
import sys
import types

import pytest

from fmm_ros.core.identify.running import RunningFriction
from fmm_ros.core.signal.analysis import select_impacts
from fmm_ros.core.signal.judging import (
    MAX_REASON_CHARS,
    Decision,
    by_trigger,
    is_taken,
    judge_with,
    latest,
    load_judge,
)
from fmm_ros.errors import BadInputError, SelectionError
from fmm_ros.workflows.results import selection_dict


class Hit:
    """What selection needs of an impact."""

    def __init__(self, impact_id, accepted, flags=()):
        self.impact_id = impact_id
        self.accepted = accepted
        self.flags = tuple(flags)


HITS = [Hit(0, True), Hit(1, True), Hit(2, False, ['clipped']), Hit(3, True)]


def test_decisions_overrule_the_flags_in_the_one_selection_rule():
    decisions = latest(
        [
            Decision(1, 'reject', 'alice', 'pulse rang twice'),
            Decision(2, 'accept', 'alice', 'clip of 1 sample, looked at it'),
            Decision(3, 'pending', 'station', mode='manual'),
        ]
    )
    selection = select_impacts(HITS, decisions=decisions)
    assert selection.chosen == (0, 2)
    assert selection.excluded == ()
    assert [d.impact_id for d in selection.judged] == [1, 2, 3]
    assert 'impact 1 rejected by alice (pulse rang twice)' in selection.note
    assert 'impact 3 held pending by station' in selection.note
    assert selection_dict(selection)['judged'][0]['verdict'] == 'reject'
    # include_flagged takes what the flags rejected, never what a person rejected.
    assert select_impacts(HITS, include_flagged=True, decisions=decisions).chosen == (0, 2)
    # Reversible: a later decision wins; 'flags' gives the verdict back to the flags.
    again = latest(
        [*decisions.values(), Decision(1, 'flags', 'alice'), Decision(3, 'accept', 'bob')]
    )
    assert select_impacts(HITS, decisions=again).chosen == (0, 1, 2, 3)
    assert [is_taken(h.impact_id, h.accepted, again) for h in HITS] == [True] * 4


def test_a_selection_left_empty_by_decisions_says_who_left_them_out():
    decisions = latest([Decision(i, 'reject', 'alice', 'bad day') for i in (0, 1, 3)])
    with pytest.raises(SelectionError) as error:
        select_impacts(HITS, decisions=decisions)
    assert 'impact 2 (clipped) flagged' in str(error.value)
    assert 'impact 0 rejected by alice (bad day)' in str(error.value)


@pytest.mark.parametrize(
    ('fields', 'words'),
    [
        ({'verdict': 'maybe'}, "verdict 'maybe' is not one of accept, reject, pending, flags"),
        ({'decided_by': '  '}, 'who decided is not given'),
        ({'decided_by': 'x' * 65}, 'decided_by is 65 characters (at most 64)'),
        ({'reason': 'r' * (MAX_REASON_CHARS + 1)}, 'reason is 501 characters (at most 500)'),
        ({'impact_id': '3'}, "impact id '3' is not an integer"),
        ({'impact_id': -1}, 'impact id -1 is outside'),
        ({'mode': 'auto'}, "mode 'auto' is not one of flags, manual, function"),
    ],
)
def test_a_malformed_decision_is_refused_naming_the_problem(fields, words):
    values = {'impact_id': 3, 'verdict': 'reject', 'decided_by': 'alice', **fields}
    with pytest.raises(BadInputError, match='decision refused') as error:
        Decision(**values)
    assert words in str(error.value)


def test_replayed_hits_find_their_decisions_by_trigger_sample():
    recorded = [
        Decision(7, 'reject', 'alice', trigger_sample_index=20_000),
        Decision(8, 'accept', 'alice', trigger_sample_index=80_000),
        Decision(7, 'accept', 'bob', trigger_sample_index=20_000),
        Decision(9, 'reject', 'bob', trigger_sample_index=5),
    ]
    found, lost = by_trigger(recorded, {20_000: 0, 80_000: 1})
    assert {i: (d.verdict, d.decided_by) for i, d in found.items()} == {
        0: ('accept', 'bob'),
        1: ('accept', 'alice'),
    }
    assert [d.impact_id for d in lost] == [9]


@pytest.fixture
def judges(monkeypatch):
    module = types.ModuleType('lab_judges')

    def peak_ok(record, result):
        return result.peak_force_n < 1500.0, f'peak {result.peak_force_n:.0f} N'

    def crashes(record, result):
        raise RuntimeError('no such channel')

    module.peak_ok = peak_ok
    module.crashes = crashes
    module.says_yes = lambda record, result: 'yes'
    monkeypatch.setitem(sys.modules, 'lab_judges', module)
    return module


def test_a_judge_function_decides_and_a_broken_one_leaves_the_hit_to_the_operator(judges):
    hard = types.SimpleNamespace(peak_force_n=1600.0)
    decision = judge_with(
        load_judge('lab_judges:peak_ok'), 'lab_judges:peak_ok', None, hard, impact_id=4
    )
    assert (decision.verdict, decision.reason, decision.mode) == (
        'reject',
        'peak 1600 N',
        'function',
    )
    assert decision.decided_by == 'lab_judges:peak_ok'
    broken = judge_with(judges.crashes, 'lab_judges:crashes', None, hard, impact_id=4)
    assert broken.verdict == 'pending'
    assert 'raised RuntimeError: no such channel' in broken.reason
    odd = judge_with(judges.says_yes, 'lab_judges:says_yes', None, hard, impact_id=4)
    assert odd.verdict == 'pending' and "returned 'yes'" in odd.reason


@pytest.mark.parametrize(
    ('spec', 'words'),
    [
        ('lab_judges', 'is not module:function'),
        ('no_such_module_xyz:f', 'cannot import no_such_module_xyz'),
        ('lab_judges:missing', 'lab_judges has no function missing'),
    ],
)
def test_a_judge_function_that_cannot_be_loaded_is_refused(judges, spec, words):
    with pytest.raises(BadInputError, match=words):
        load_judge(spec)


def test_the_running_mu_without_a_rejected_hit_is_the_mu_it_never_had():
    fits = [(0, 'low', 0.110, 0.002), (1, 'low', 0.150, 0.002), (2, 'high', 0.112, 0.003)]
    running = RunningFriction()
    for fit in fits:
        running.add(*fit)
    removed = running.remove(1)
    fresh = RunningFriction()
    fresh.add(*fits[0])
    expected = fresh.add(*fits[2])
    assert removed.impact_id == 1 and removed.impact_ids == (0, 2)
    assert removed.mu == expected.mu and removed.mu_stderr == expected.mu_stderr
    assert removed.consistency_p_value == expected.consistency_p_value
    assert [(lv.level, lv.count) for lv in removed.levels] == [('low', 1), ('high', 1)]
    back = running.add(1, 'low', 0.150, 0.002)
    assert back.impact_ids == (0, 2, 1) and back.count == 3
    running.remove(0), running.remove(2)
    empty = running.remove(1)
    assert empty.count == 0 and math.isnan(empty.mu) and empty.impact_ids == ()
