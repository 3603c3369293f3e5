"""The damaged-hit matrix: each fault -> flagged / refused / mu returned, and clean false flags.

Run: .venv/bin/python benchmarks/bench_damage.py [--cases N] [--clean N]

Records come from test/damaged_records.py, never from the flag code: by default both from the
independent generator test/worlds (its plant, hits, DAQ chain and damage kinds; each record
streamed by sample index as live capture and bag replay see it) and from our excitation and
physics pieces with the fault done as the lab suffers it (see its docstring).
Each case is a session of three hits (low, medium, high) fitted as `fmm fit` fits it
(`select_records`, then `fit_impacts` with its defaults: each hit's start fitted):

- all three hits damaged: the fit should refuse (no clean hit);
- one hit damaged, two clean: the fit should return mu from the clean two and name the
  damaged one.

A mu returned without warning is confidently wrong when it is off the true mu by more than
2 % or by more than 3 of its own standard errors (both are counted). "mu if fitted anyway"
fits the same damaged hits with include_flagged, for scale: what the flags protect against.
Clean sessions give the false-flag rate per hit (damage flags, and `unsettled` apart, which
judges the record's length, not its samples) and the same mu errors as a baseline.
"""

import argparse
import collections
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))

from damaged_records import FAULTS, session, worlds_session  # noqa: E402
from results_file import QUICK_HELP, recorded

from fmm_ros.workflows.session import analyse, fit_impacts, impact_ids, select_records  # noqa: E402

# Flags that say the samples are damaged (the others judge the record, not its samples).
RECORD_FLAGS = ('unsettled', 'overlap', 'out_of_tolerance')
WRONG_PERCENT = 2.0
WRONG_SIGMAS = 3.0


def fit_session(records, include_flagged=False):
    """('refused', reason) or ('mu', mu, stderr, selection) as `fmm fit` would end."""
    try:
        selection = select_records(records, include_flagged=include_flagged)
        by_id = dict(zip(impact_ids(records), records, strict=True))
        fit = fit_impacts(by_id, selection.chosen)  # fmm fit's defaults: each start fitted
    except ValueError as error:  # SelectionError, FitError, or samples the fit cannot take
        return ('refused', getattr(error, 'reason', type(error).__name__))
    return ('mu', fit.mu, fit.mu_stderr, selection)


def judge(outcome, true_mu):
    """'refused', 'ok' or 'wrong' (confidently: off by > 2 % or > 3 sigma), and the error %."""
    if outcome[0] == 'refused':
        return 'refused', np.nan
    _, mu, stderr, _ = outcome
    error = abs(mu - true_mu)
    percent = 100 * error / true_mu
    wrong_percent = percent > WRONG_PERCENT
    wrong_sigma = error > WRONG_SIGMAS * stderr
    return {
        (False, False): 'ok',
        (True, False): 'wrong_2pc',
        (False, True): 'wrong_3sigma',
        (True, True): 'wrong_both',
    }[(wrong_percent, wrong_sigma)], percent


GENERATORS = {'worlds': worlds_session, 'excitation': session}


def run_fault(fault, cases, seed0, session=session):
    """Counts for one fault over cases sessions of each kind."""
    stats = collections.Counter()
    anyway = []
    for case in range(cases):
        hits, mu = session(fault, seed0 + case)
        records = [hit.record for hit in hits]
        summary = analyse(records)
        stats['hits'] += 3
        stats['flagged'] += sum(
            bool(set(impact.flags) - set(RECORD_FLAGS)) for impact in summary.impacts
        )
        verdict, _ = judge(fit_session(records), mu)
        stats[f'all:{verdict}'] += 1
        anyway.append(judge(fit_session(records, include_flagged=True), mu)[1])
        position = case % 3
        hits, mu = session(fault, seed0 + 10_000 + case, damaged=(position,))
        records = [hit.record for hit in hits]
        outcome = fit_session(records)
        verdict, _ = judge(outcome, mu)
        stats[f'one:{verdict}'] += 1
        if outcome[0] == 'mu':
            named = {entry[0] for entry in outcome[3].excluded}
            stats['one:named'] += position in named
    return stats, anyway


def run_clean(sessions, seed0, session=session):
    """False flags per hit and the mu errors of clean sessions."""
    stats = collections.Counter()
    flag_names = collections.Counter()
    errors = []
    for case in range(sessions):
        hits, mu = session('', seed0 + case, damaged=())
        records = [hit.record for hit in hits]
        summary = analyse(records)
        for impact in summary.impacts:
            stats['hits'] += 1
            damage = set(impact.flags) - set(RECORD_FLAGS)
            stats['damage_flagged'] += bool(damage)
            stats['unsettled'] += 'unsettled' in impact.flags
            flag_names.update(damage)
        verdict, percent = judge(fit_session(records), mu)
        stats[verdict] += 1
        errors.append(percent)
    return stats, flag_names, np.array(errors)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--cases', type=int, default=30, help='sessions per fault and kind')
    parser.add_argument('--clean', type=int, default=200, help='clean sessions (3 hits each)')
    parser.add_argument(
        '--generator',
        choices=(*GENERATORS, 'both'),
        default='both',
        help='worlds: the independent generator; excitation: ours (default: both)',
    )
    parser.add_argument('--quick', action='store_true', help=QUICK_HELP)
    args = parser.parse_args()
    if args.quick:
        args.cases, args.clean = 1, 2
        args.generator = next(iter(GENERATORS))
    for name, generator in GENERATORS.items():
        if args.generator in (name, 'both'):
            matrix(name, generator, args.cases, args.clean)


def matrix(name, generator, cases, clean):
    """The fault table and the clean statistics of one generator."""
    began = time.perf_counter()
    print(
        f'\n{name}: damaged-hit matrix, {cases} sessions per fault with all 3 hits damaged, '
        f'{cases} with 1 of 3'
    )
    header = (
        f'{"fault":<16} {"flagged":>9} | {"3 of 3: refused":>15} {"mu ok":>6} {">2%":>4} '
        f'{">3σ":>4} | {"1 of 3: mu ok":>13} {"named":>6} {"refused":>7} {">2%":>4} {">3σ":>4} | '
        f'{"mu if fitted anyway: median, max |err|":>38}'
    )
    print(header)
    print('-' * len(header))
    wrong = collections.Counter()
    for number, fault in enumerate(FAULTS):
        stats, anyway = run_fault(fault, cases, 1_000 * (number + 1), generator)
        counts = {}
        for kind in ('all', 'one'):
            counts[kind, '2pc'] = stats[f'{kind}:wrong_2pc'] + stats[f'{kind}:wrong_both']
            counts[kind, 'sigma'] = stats[f'{kind}:wrong_3sigma']
            wrong['2pc'] += counts[kind, '2pc']
            wrong['sigma'] += counts[kind, 'sigma']
        anyway = np.array(anyway)
        returned = anyway[np.isfinite(anyway)]
        scale = (
            f'{np.median(returned):6.1f} % {np.max(returned):6.1f} % '
            f'({returned.size}/{anyway.size} fitted)'
            if returned.size
            else 'all refused'
        )
        print(
            f'{fault:<16} {stats["flagged"]:>4}/{stats["hits"]:<4} | '
            f'{stats["all:refused"]:>15} {stats["all:ok"]:>6} {counts["all", "2pc"]:>4} '
            f'{counts["all", "sigma"]:>4} | {stats["one:ok"]:>13} {stats["one:named"]:>6} '
            f'{stats["one:refused"]:>7} {counts["one", "2pc"]:>4} {counts["one", "sigma"]:>4} | '
            f'{scale:>38}'
        )
    print(
        f'confident wrong mu over the matrix: {wrong["2pc"]} off by > 2 %, '
        f'{wrong["sigma"]} off by < 2 % but > 3 standard errors'
    )
    stats, names, errors = run_clean(clean, 900_000, generator)
    print(
        f'clean: {clean} sessions, {stats["hits"]} hits: damage flags on '
        f'{stats["damage_flagged"]} ({100 * stats["damage_flagged"] / stats["hits"]:.2f} %)'
        f'{" " + dict(names).__repr__() if names else ""}; unsettled on {stats["unsettled"]} '
        f'({100 * stats["unsettled"] / stats["hits"]:.2f} %)'
    )
    fitted = errors[np.isfinite(errors)]
    print(
        f'clean fits: {stats["ok"]} ok, {stats["refused"]} refused, off by > 2 %: '
        f'{stats["wrong_2pc"] + stats["wrong_both"]}, off by < 2 % but > 3 standard errors: '
        f'{stats["wrong_3sigma"]}; |mu error| median {np.median(fitted):.3f} %, '
        f'max {np.max(fitted):.3f} %'
    )
    print(f'({time.perf_counter() - began:.0f} s)')


if __name__ == '__main__':
    with recorded('bench_damage', quick='--quick' in sys.argv):
        main()
