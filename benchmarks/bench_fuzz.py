"""Fuzzing the file readers: outcomes of mutated MCAP/sqlite3 bags, CSV, NPZ, MAT and TDMS files.

Run: .venv/bin/python benchmarks/bench_fuzz.py [--per-target N] [--seed S]

Each mutated file goes through the `fmm` command a user would run on it, in a child forked
from a warm worker, under an address-space limit and a timeout (test/fuzz_files.py). Prints
per format and mutation: files, and how each ended (ok: read, the mutation harmless or not
detectable, like a flipped bit in an unchecksummed sample; damage: read with the damage
named, exit 1; error: refused with a one-line error naming the file, exit 2; traceback, hang,
crash: failures); then the peak address-space growth against the file's size and the time per
file. fmm reads no UFF file (it writes UFF 58), so none is fuzzed. Ends with status 1 if any
file shows what test/test_fuzz.py refuses (`fuzz_files.failures`): the default 1,100-file
sweep is that test's check over many more files.
"""

import argparse
import collections
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))

from fuzz_files import MUTATIONS, TARGETS, failures, fuzz  # noqa: E402
from results_file import QUICK_HELP, recorded

VERDICTS = ('ok', 'damage', 'error', 'traceback', 'hang', 'crash')


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--per-target', type=int, default=100, help='mutated files per target')
    parser.add_argument('--seed', type=int, default=7)
    parser.add_argument('--quick', action='store_true', help=QUICK_HELP)
    args = parser.parse_args()
    if args.quick:
        args.per_target = 2
    began = time.perf_counter()
    cases, outcomes = fuzz(args.per_target, args.seed)
    elapsed = time.perf_counter() - began
    table = collections.defaultdict(collections.Counter)
    kinds = collections.defaultdict(collections.Counter)
    for case, outcome in zip(cases, outcomes, strict=True):
        table[case.target][outcome.verdict] += 1
        kinds[case.kind][outcome.verdict] += 1
    header = f'{"target":<18}{"command":<28}{"files":>6}' + ''.join(f'{v:>10}' for v in VERDICTS)
    print(header)
    print('-' * len(header))
    for target in TARGETS:
        counts = table[target]
        command = ' '.join(TARGETS[target][:1])
        print(
            f'{target:<18}{"fmm " + command:<28}{sum(counts.values()):>6}'
            + ''.join(f'{counts[v]:>10}' for v in VERDICTS)
        )
    print('-' * len(header))
    for kind in MUTATIONS:
        counts = kinds[kind]
        print(
            f'{kind:<46}{sum(counts.values()):>6}' + ''.join(f'{counts[v]:>10}' for v in VERDICTS)
        )
    total = collections.Counter(outcome.verdict for outcome in outcomes)
    print(f'{"all":<46}{len(cases):>6}' + ''.join(f'{total[v]:>10}' for v in VERDICTS))
    growth = sorted(zip(cases, outcomes, strict=True), key=lambda pair: -pair[1].peak_growth_bytes)
    worst_case, worst = growth[0]
    beyond = sum(
        outcome.peak_growth_bytes > (1 << 20) + 4 * case.size_bytes for case, outcome in growth
    )
    print(
        f'\npeak address-space growth: max {worst.peak_growth_bytes / 1e6:.1f} MB '
        f'({worst_case.target}, {worst_case.description}, file {worst_case.size_bytes / 1e6:.2f} '
        f'MB), then {growth[1][1].peak_growth_bytes / 1e6:.1f} MB; median '
        f'{growth[len(growth) // 2][1].peak_growth_bytes / 1e6:.2f} MB; files growing more '
        f'than 1 MB + 4 x their size: {beyond}'
    )
    broken = total['traceback'] + total['hang'] + total['crash']
    print(
        f'{len(cases)} mutated files in {elapsed:.0f} s ({1e3 * elapsed / len(cases):.0f} ms a '
        f'file, forked, warm); tracebacks, hangs and crashes: {broken}'
    )
    for case, outcome in zip(cases, outcomes, strict=True):
        if outcome.verdict in ('traceback', 'hang', 'crash'):
            print(f'  {case.name}: {case.description} -> {outcome.verdict}: {outcome.message}')
    failed = {name: found for name, found in failures(cases, outcomes).items() if found}
    for name, found in failed.items():
        print(f'FAILED, {name}: {len(found)} files, first {found[0]}')
    return 1 if failed else 0


if __name__ == '__main__':
    with recorded('bench_fuzz', quick='--quick' in sys.argv):
        raise SystemExit(main())
