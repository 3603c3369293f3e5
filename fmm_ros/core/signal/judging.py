"""Who keeps a hit: the operator's and a judge function's decisions over the flags.

The analyzer's flags accept or reject every impact. A decision overrules them for one impact:
`accept` takes it (a flagged hit the operator has looked at), `reject` leaves it out (a hit
the operator saw go wrong), `pending` holds it out until someone decides (manual mode), and
`flags` gives the verdict back to the flags. Decisions are reversible: the newest one for an
impact wins (`latest`). `select_impacts` applies them, so the fitter, the live mu, replay,
the report and campaigns take the same hits.

Three modes (`MODES`) say who judges a new hit: `flags` (the analyzer's verdict stands),
`manual` (each hit waits, `pending`, for the operator) and `function` (a user's
`module:function`, given the hit's record and result, returns the verdict: `load_judge`).
Decisions are keyed by impact id (an opaque key) and carry the trigger sample index, so a
replay that numbers the hits afresh still finds the hit a decision was about.
"""

import importlib
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

from fmm_ros.errors import BadInputError

VERDICTS = ('accept', 'reject', 'pending', 'flags')
"""What a decision says about its impact (see the module doc)."""
MODES = ('flags', 'manual', 'function')
"""Who judges a new hit."""
TAKEN = {'accept': True, 'reject': False, 'pending': False}
"""Whether a fit takes an impact under each overruling verdict (`flags`: the flags decide)."""
MAX_NAME_CHARS = 64
"""Longest `decided_by` [characters]: an operator's name or a function's `module:function`."""
MAX_REASON_CHARS = 500
"""Longest reason [characters]."""


@dataclass(frozen=True)
class Decision:
    """One decision about one impact: its verdict, who made it and why."""

    impact_id: int
    verdict: str
    decided_by: str
    reason: str = ''
    mode: str = 'manual'
    trigger_sample_index: int = -1
    """The impact's trigger sample (-1: not known): how a replay finds the hit again."""
    stamp_ns: int = 0
    """When it was decided (wall clock) [ns]."""

    def __post_init__(self) -> None:
        problems = []
        if isinstance(self.impact_id, bool) or not isinstance(self.impact_id, int):
            problems.append(f'impact id {self.impact_id!r} is not an integer')
        elif not 0 <= self.impact_id < 2**32:
            problems.append(f'impact id {self.impact_id} is outside 0..2^32-1')
        if self.verdict not in VERDICTS:
            problems.append(f'verdict {self.verdict!r} is not one of {", ".join(VERDICTS)}')
        if self.mode not in MODES:
            problems.append(f'mode {self.mode!r} is not one of {", ".join(MODES)}')
        if not isinstance(self.decided_by, str) or not self.decided_by.strip():
            problems.append('who decided is not given (decided_by is empty)')
        elif len(self.decided_by) > MAX_NAME_CHARS:
            problems.append(
                f'decided_by is {len(self.decided_by)} characters (at most {MAX_NAME_CHARS})'
            )
        if not isinstance(self.reason, str):
            problems.append(f'reason {self.reason!r} is not text')
        elif len(self.reason) > MAX_REASON_CHARS:
            problems.append(f'reason is {len(self.reason)} characters (at most {MAX_REASON_CHARS})')
        if problems:
            raise BadInputError(f'decision refused: {"; ".join(problems)}')

    @property
    def taken(self) -> bool | None:
        """Whether a fit takes the impact: True, False, or None (the flags decide)."""
        return TAKEN.get(self.verdict)

    def describe(self) -> str:
        """'impact 3 rejected by alice (pulse rang twice)'."""
        words = {'accept': 'accepted', 'reject': 'rejected', 'pending': 'held pending'}
        word = words.get(self.verdict, 'returned to its flags')
        return f'impact {self.impact_id} {word} by {self.decided_by}' + (
            f' ({self.reason})' if self.reason else ''
        )


def latest(decisions: Iterable[Decision]) -> dict[int, Decision]:
    """The newest decision per impact id, in the order given (a later one overrules)."""
    newest: dict[int, Decision] = {}
    for decision in decisions:
        newest[decision.impact_id] = decision
    return newest


def by_trigger(
    decisions: Iterable[Decision], trigger_ids: Mapping[int, int]
) -> tuple[dict[int, Decision], list[Decision]]:
    """Decisions re-keyed to the impact ids of a replay: trigger sample index -> its impact id.

    Returns the decisions that found their hit (newest per hit, under the replay's ids) and
    those that did not (no hit at their trigger sample: said, never dropped silently).
    """
    found, lost = [], []
    for decision in decisions:
        impact_id = trigger_ids.get(decision.trigger_sample_index)
        if impact_id is None:
            lost.append(decision)
        else:
            found.append(_renumbered(decision, impact_id))
    return latest(found), lost


def _renumbered(decision: Decision, impact_id: int) -> Decision:
    return Decision(
        impact_id,
        decision.verdict,
        decision.decided_by,
        decision.reason,
        decision.mode,
        decision.trigger_sample_index,
        decision.stamp_ns,
    )


JudgeFunction = Callable[[object, object], object]
"""A user's judge: f(record, result) -> bool or (bool, reason)."""


def load_judge(spec: str) -> JudgeFunction:
    """The user function `module:function` names (BadInputError saying what is wrong)."""
    module_name, colon, name = spec.partition(':')
    if not (colon and module_name and name):
        raise BadInputError(f'judge function {spec!r} is not module:function')
    try:
        module = importlib.import_module(module_name)
    except ImportError as error:
        raise BadInputError(
            f'judge function {spec!r}: cannot import {module_name}: {error}'
        ) from None
    function = getattr(module, name, None)
    if not callable(function):
        raise BadInputError(f'judge function {spec!r}: {module_name} has no function {name}')
    return function


def judge_with(
    function: JudgeFunction,
    spec: str,
    record: object,
    result: object,
    *,
    impact_id: int,
    trigger_sample_index: int = -1,
    stamp_ns: int = 0,
) -> Decision:
    """The decision `function` makes on one hit (its ImpactRecord and ImpactResult).

    It may return a bool or (bool, reason). A function that raises, or returns anything else,
    decides nothing: the hit is held `pending` for the operator, the reason saying why.
    """
    try:
        answer = function(record, result)
    except Exception as error:  # a user's code: its failure must not take the node down
        verdict, reason = 'pending', f'{spec} raised {type(error).__name__}: {error}'
    else:
        keep, reason = answer if isinstance(answer, tuple) and len(answer) == 2 else (answer, '')
        if isinstance(keep, bool) and isinstance(reason, str):
            verdict = 'accept' if keep else 'reject'
        else:
            verdict, reason = 'pending', f'{spec} returned {answer!r}, not a bool or (bool, reason)'
    return Decision(
        impact_id,
        verdict,
        spec[:MAX_NAME_CHARS],
        reason[:MAX_REASON_CHARS],
        'function',
        trigger_sample_index,
        stamp_ns,
    )


def is_taken(impact_id: int, accepted: bool, decisions: Mapping[int, Decision]) -> bool:
    """Whether a fit takes an impact its flags accepted or not, under the decisions given."""
    decision = decisions.get(impact_id)
    return accepted if decision is None or decision.taken is None else decision.taken
