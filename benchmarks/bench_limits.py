"""The stated detection limits, tried on worlds the product was not tuned on.

Run: .venv/bin/python benchmarks/bench_limits.py [--quick] [--cases N] [--seed S]
     [--worlds W,...] [--multiples 1.5] [--effects E,...]

`fmm diagnose` states, for every candidate, the size from which the session's records would
show it (`Candidate.detection_limit`: what `none` cannot rule out). `bench_diagnose` counts
the worlds' own draws against it; here the size is set from it. Each case is a session of a
held-out world (`heldout.ROLES`) with its hits, mu, chain and noise drawn once:

1. diagnosed clean (each effect at 1e-9 of its drawn size, so a world re-centres the hits for
   an asymmetry as it does for a real one), and each candidate's stated limit read;
2. the same hits, chain and noise with one effect at `MULTIPLES` of that limit (its other
   parameters and its sign drawn as the worlds draw them, `heldout.cases.effect_fields`),
   diagnosed again.

Counted per effect: the sessions whose effect is named at half and at twice the stated size.
A limit that holds names nearly every effect at twice it; at half it, an effect is still named
where the whole-misfit rule or its signature carries it (the limit is where naming is assured,
not where it stops). A clean session states a second mode's limit over the band its hits
excite (`starts.mode_limit_probes`): the mode is set where that limit is taken (its curve's
least, at the largest damping ratio probed) and drawn from a stream of its own, so the other
effects' draws are those of the runs before it.

A full run writes its section of RESULTS.md (one per seed); --quick (one session, two effects,
one world) writes nothing, nor does a run at other multiples (`--multiples 1.5`: the size
a stated limit is held to) or of some effects only (`--effects`).
"""

import argparse
import math
import statistics
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from bench_diagnose import DEFAULT_SEED, HIDDEN_SIZE, SHORT, TARGET_FALSE_ALARMS
from results_file import QUICK_HELP, write_section

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'test'))
from heldout import HELD_OUT, ROLES  # noqa: E402
from heldout.cases import MU_RANGE, WORLDS, effect_fields, kinds_of, session_of  # noqa: E402
from heldout.lab import Effects  # noqa: E402

from fmm_ros.core.diagnose.result import Candidate
from fmm_ros.core.diagnose.starts import SECOND_MODE_DAMPING_RATIOS
from fmm_ros.core.diagnose.workflow import diagnose
from fmm_ros.core.identify.spec import start_options
from fmm_ros.core.physics.terms import EFFECT_SIZE
from fmm_ros.workflows.results import detection_limit_dict

MULTIPLES = (0.5, 2.0)
"""Sizes the effects are set to, as multiples of the limit their clean session stated."""
CLEAN_FRACTION = 1e-9
"""A clean session's effect, as a fraction of its drawn size: nothing to see, but the world
treats the session as one of that effect (it re-centres the hits for an asymmetry)."""
TARGET_MULTIPLE = 1.5
"""The multiple of a clean session's stated limit an effect is held to be named from."""
AIM_MULTIPLE = 1.2
"""The multiple aimed for: reported beside the target, judged the same way."""
TARGET_NAMED = 0.9
"""The share of sessions, per effect, that must name an effect drawn at TARGET_MULTIPLE."""
LEVELS_N = (450.0, 1000.0, 1450.0)
QUICK_EFFECTS = ('cubic_stiffness', 'mu_drift', 'second_mode')


@dataclass
class Check:
    """What one world's cases found: per effect, the limits stated and the names at each size."""

    world: str
    multiples: tuple[float, ...] = MULTIPLES
    limits: dict[str, list[float]] = field(default_factory=dict)
    named: dict[str, dict[float, list[int]]] = field(default_factory=dict)
    """effect -> multiple -> [sessions that named the effect, sessions]."""
    units: dict[str, str] = field(default_factory=dict)
    unstated: dict[str, int] = field(default_factory=dict)
    """Clean sessions that stated no finite limit for the effect."""
    false_alarms: int = 0
    """Clean sessions that named anything."""
    clean: int = 0
    misses: list[str] = field(default_factory=list)
    """Each effect not named at a multiple of at least TARGET_MULTIPLE, in words."""

    def table(self) -> list[str]:
        """The markdown table of this world."""
        lines = [
            '| effect | stated limit, median (range) | '
            + ''.join(f'named at {m:g}x | ' for m in self.multiples)
            + 'no limit |',
            '|---|---|' + '---|' * len(self.multiples) + '---|',
        ]
        for effect, limits in self.limits.items():
            counts = self.named[effect]
            tallies = [counts.get(m, [0, 0]) for m in self.multiples]
            stated = (
                f'{statistics.median(limits):.2g} {self.units[effect]} '
                f'({min(limits):.2g}-{max(limits):.2g})'
                if limits
                else '-'
            )
            lines.append(
                f'| {SHORT[effect]} | {stated} | '
                + ''.join(f'{named} of {total} | ' for named, total in tallies)
                + f'{self.unstated.get(effect, 0)} |'
            )
        return lines

    def totals(self) -> list[str]:
        """The figures under the table."""
        lines = []
        for multiple in self.multiples:
            named = sum(c.get(multiple, [0, 0])[0] for c in self.named.values())
            total = sum(c.get(multiple, [0, 0])[1] for c in self.named.values())
            lines.append(f'at {multiple:g}x the stated size: named {named} of {total}')
        lines.append(f'clean sessions that named anything: {self.false_alarms} of {self.clean}')
        return lines

    def targets(self) -> list[str]:
        """Per effect, the share named at TARGET_MULTIPLE and AIM_MULTIPLE, each met or not.

        The target asks at least TARGET_NAMED of every effect's sessions at TARGET_MULTIPLE; the
        aim asks the same at AIM_MULTIPLE. Then the clean sessions' false alarms.
        """
        lines = []
        for multiple, what in ((TARGET_MULTIPLE, 'target'), (AIM_MULTIPLE, 'aim')):
            if multiple not in self.multiples:
                continue
            rates = {
                effect: counts[multiple]
                for effect, counts in self.named.items()
                if counts.get(multiple, [0, 0])[1]
            }
            if not rates:
                continue
            worst = min(rates, key=lambda e: rates[e][0] / rates[e][1])
            share = rates[worst][0] / rates[worst][1]
            per_kind = ', '.join(f'{SHORT[e]} {n[0]} of {n[1]}' for e, n in rates.items())
            lines.append(
                f'named at {multiple:g}x the stated size, per kind: {per_kind}; worst '
                f'{SHORT[worst]} {share:.2f} ({what} at least {TARGET_NAMED:.2f} per kind) '
                f'{"met" if share >= TARGET_NAMED else "NOT met"}'
            )
        if self.clean:
            alarms = self.false_alarms / self.clean
            met = 'met' if alarms <= TARGET_FALSE_ALARMS else 'NOT met'
            lines.append(
                f'clean sessions that named anything: {alarms:.2f} (target at most '
                f'{TARGET_FALSE_ALARMS:.2f}) {met}'
            )
        return lines


def check(
    name: str,
    cases: int,
    seed: int,
    effects: tuple[str, ...] | None = None,
    multiples: tuple[float, ...] = MULTIPLES,
) -> Check:
    """A world's `Check`: `cases` sessions clean, then each effect at `multiples` of its limit."""
    world = WORLDS[name]
    kinds = kinds_of(world)
    chosen = [e for e in (effects or HIDDEN_SIZE) if e in kinds and e != 'second_mode']
    if 'second_mode' in kinds and (effects is None or 'second_mode' in effects):
        chosen.append('second_mode')
    found = Check(name, multiples)
    for number in range(cases):
        rng = np.random.default_rng([seed, number])
        mu = float(rng.uniform(*MU_RANGE))
        levels = rng.permutation(LEVELS_N)
        session = (world, mu, levels, int(rng.integers(2**63)))
        cleans = {}
        for effect in chosen:
            # A mode's fields come from a stream of their own: the others' draws stay as they were.
            drawn = np.random.default_rng([seed, number, 1]) if effect == 'second_mode' else rng
            fields = effect_fields(effect, mu, drawn)
            size_field = HIDDEN_SIZE[effect]
            sign = math.copysign(1.0, fields[size_field])
            # A mode's size is its mass, under which it shows: twice the size is half the mass.
            inverse = EFFECT_SIZE.get(effect, ('', False))[1]
            centred = effect == 'asymmetric_friction'
            if centred not in cleans:
                clean = fields[size_field] * CLEAN_FRACTION ** (-1 if inverse else 1)
                cleans[centred] = _diagnosed(session, Effects(**{**fields, size_field: clean}))
                found.clean += 1
                found.false_alarms += bool(cleans[centred].named_effects)
            candidate = next(c for c in cleans[centred].candidates if c.effect == effect)
            limit = candidate.detection_limit
            if candidate.detection_limit_by_frequency:
                fields = {**fields, **_least_visible_mode(candidate)}
            found.limits.setdefault(effect, [])
            counts = found.named.setdefault(effect, {})
            if not (math.isfinite(limit) and limit > 0.0):
                found.unstated[effect] = found.unstated.get(effect, 0) + 1
                continue
            found.limits[effect].append(limit)
            found.units[effect] = detection_limit_dict(effect, limit)['unit']
            for multiple in multiples:
                size = limit / multiple if inverse else multiple * limit
                hidden = Effects(**{**fields, size_field: sign * size})
                result = _diagnosed(session, hidden)
                tally = counts.setdefault(multiple, [0, 0])
                tally[0] += effect in result.named_effects
                tally[1] += 1
                if effect not in result.named_effects and multiple >= min(
                    TARGET_MULTIPLE, AIM_MULTIPLE
                ):
                    verdict = ' '.join(result.verdict.split())[:200]
                    found.misses.append(
                        f'{SHORT[effect]} at {multiple:g}x ({sign * size:.3g} '
                        f'{found.units[effect]}), case {number}: named '
                        f'{", ".join(result.named_effects) or "none"}; {verdict}'
                    )
        print(f'  {name} case {number}: done', flush=True)
    print(f'\n{name} (held out world)')
    print('\n'.join(found.table() + found.totals() + found.targets()), flush=True)
    print('misses:' if found.misses else 'misses: none')
    for miss in found.misses:
        print(f'  {miss}', flush=True)
    return found


def _least_visible_mode(candidate: Candidate) -> dict:
    """Where a second mode's stated limit is taken, as the worlds' fields.

    The frequency of its curve's least (`detection_limit_by_frequency`), at the largest damping
    ratio probed (`starts.mode_limit_probes`).
    """
    frequency_hz, _ = min(candidate.detection_limit_by_frequency, key=lambda point: point[1])
    return {'mode_hz': frequency_hz, 'mode_damping_ratio': max(SECOND_MODE_DAMPING_RATIOS)}


def _diagnosed(session: tuple, effects: Effects):
    """The diagnosis of a session (world, mu, levels, seed of its draws) with these effects."""
    world, mu, levels, seed = session
    records, starts = session_of(world, effects, mu, np.random.default_rng(seed), levels)
    return diagnose(records, **start_options(starts))


def markdown(checks: list[Check], cases: int) -> str:
    """The RESULTS.md section of some worlds' checks."""
    parts = []
    for found in checks:
        parts.append(f'**{found.world}** ({cases} sessions)\n')
        parts.append('\n'.join(found.table()) + '\n')
        lines = found.totals() + found.targets()
        lines += [f'missed: {miss}' for miss in found.misses]
        parts.append('\n'.join(f'- {line}' for line in lines) + '\n')
    return '\n'.join(parts)


def main() -> None:
    """Check the stated limits on the held-out worlds and write the RESULTS.md section."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help=QUICK_HELP)
    parser.add_argument('--cases', type=int, default=8, help='sessions a world')
    parser.add_argument('--seed', type=int, default=DEFAULT_SEED, help='draws the sessions')
    parser.add_argument(
        '--worlds',
        type=lambda text: tuple(text.split(',')),
        default=(),
        help='check only these held-out worlds (comma-separated names of heldout.ROLES)',
    )
    parser.add_argument(
        '--multiples',
        type=lambda text: tuple(float(m) for m in text.split(',')),
        default=MULTIPLES,
        help='sizes to set each effect to, as multiples of its stated limit (comma-separated)',
    )
    parser.add_argument(
        '--effects',
        type=lambda text: tuple(text.split(',')),
        default=None,
        help='try only these effects (comma-separated diagnosis names)',
    )
    args = parser.parse_args()
    held_out = [name for name in WORLDS if ROLES[name] == HELD_OUT]
    unknown = sorted(set(args.worlds) - set(held_out))
    if unknown:
        parser.error(f'not a held-out world: {", ".join(unknown)}; held out: {", ".join(held_out)}')
    worlds = held_out[:1] if args.quick else [w for w in held_out if w in (args.worlds or held_out)]
    cases = 1 if args.quick else args.cases
    effects = QUICK_EFFECTS if args.quick else args.effects
    checks = [check(name, cases, args.seed, effects, args.multiples) for name in worlds]
    partial = args.multiples != MULTIPLES or args.effects is not None
    seed = f', seed {args.seed}' if args.seed != DEFAULT_SEED else ''
    chosen = f' [{", ".join(args.worlds)}]' if args.worlds else ''
    write_section(
        f'bench_limits, held out worlds{chosen}{seed}',
        markdown(checks, cases),
        quick=args.quick or partial,
    )


if __name__ == '__main__':
    main()
