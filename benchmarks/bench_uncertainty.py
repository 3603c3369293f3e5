"""Honest mu, honest errors: coverage, false rejection and bias over many independent sessions.

Run: .venv/bin/python benchmarks/bench_uncertainty.py [--sessions N] [--scenarios 0 2 ...]

Sessions come from the independent generator (test/worlds: continuous-force hits sampled
afterwards, its own stick-slip solver and DAQ chain), three hits each, cut from one continuous
recording so every hit finds the rig where friction left it (`test/calibration.py` has the
scenarios and the statistics). Each session is fitted twice in the same run: as the exact-force
fit ('today': the measured force as exact, the velocity as measured, block-sum
errors, each hit's start fitted as the fitter node did) and as `fmm fit`, the report and the
fitter node fit now ('now'). Printed per scenario and fit: the share of sessions with
|mu - true mu| <= 2 standard errors (target >= 90 %), the share in which the one-mu test
rejects the true single mu at alpha = 0.05 (target <= ~5 %) and at 0.001, the mean and largest
relative error of mu (target within 0.5 %), the RMS of error / standard error (1 when honest),
and the median fit time.
"""

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))

from calibration import FITTERS, SCENARIOS, Calibration, calibrate  # noqa: E402
from results_file import QUICK_HELP, recorded

TARGET_COVERAGE = 0.90
TARGET_REJECTION = 0.05


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--sessions', type=int, default=100, help='sessions per scenario')
    parser.add_argument(
        '--scenarios',
        type=int,
        nargs='+',
        default=list(range(len(SCENARIOS))),
        help=' '.join(f'{i}: {s.name};' for i, s in enumerate(SCENARIOS)),
    )
    parser.add_argument('--quick', action='store_true', help=QUICK_HELP)
    args = parser.parse_args()
    if args.quick:
        args.sessions, args.scenarios = 2, args.scenarios[:1]
    print(
        f'{args.sessions} sessions a scenario, 3 hits each (independent generator); '
        f"'today': the exact-force fit, 'now': fit_friction as fmm fit runs it"
    )
    print(
        f'  {"scenario / fit":<40} {"coverage":>8} {"p<0.05":>7} {"p<0.001":>8} '
        f'{"bias":>9} {"worst":>8} {"rms z":>6} {"time":>6}'
    )
    verdicts = []
    for index in args.scenarios:
        scenario = SCENARIOS[index]
        start = time.perf_counter()
        results = calibrate((scenario.session(seed) for seed in range(args.sessions)), FITTERS)
        print(f'  {scenario.name} ({time.perf_counter() - start:.0f} s)')
        for name, result in results.items():
            print(f'    {name:<38} ' + _row(result))
        now = results['now']
        verdicts.append(
            now.coverage >= TARGET_COVERAGE
            and now.rejection <= TARGET_REJECTION + _binomial_allowance(args.sessions)
            and now.worst < 5e-3
        )
    print(
        f'\n=> coverage >= {TARGET_COVERAGE:.0%}, one-mu rejections <= {TARGET_REJECTION:.0%} '
        f'(+ two binomial standard deviations at {args.sessions} sessions), mu within 0.5 %: '
        f'{"met" if all(verdicts) else "MISSED"} in {sum(verdicts)} of {len(verdicts)} scenarios'
    )


def _row(result: Calibration) -> str:
    median_s = sorted(result.seconds)[len(result.seconds) // 2]
    return (
        f'{result.coverage:8.0%} {result.rejection:7.0%} {result.strict_rejection:8.0%} '
        f'{result.bias:+9.1e} {result.worst:8.1e} {result.rms_z:6.2f} {median_s:5.2f}s'
    )


def _binomial_allowance(sessions: int) -> float:
    """Two standard deviations of a 5 % rate measured over `sessions` sessions."""
    return 2.0 * (TARGET_REJECTION * (1 - TARGET_REJECTION) / sessions) ** 0.5


if __name__ == '__main__':
    with recorded('bench_uncertainty', quick='--quick' in sys.argv):
        main()
