"""Diagnose workflow: a randomised hidden-effect sweep, and the time of one diagnosis.

Run: .venv/bin/python benchmarks/bench_diagnose.py [--cases N] [--seed S] [--repeats R]
     [--session-hits H]

The sweep draws N sessions (three impacts of 33 s at random hammer levels, 0.2 N / 1e-4 m/s
noise, a random friction coefficient) per hidden effect and for 'none', each with the effect
sized 1-4x the velocity noise after the base fit (`fmm_ros.sim.hidden_effects`), diagnoses
them, and prints the confusion matrix (rows: hidden, columns: named), the accuracy, the median
gap reduction where an effect was hidden, and every miss. Then the time of one diagnosis of
three impacts (all candidates) against the same diagnosis with every candidate refitted from
its default parameters, no start from the signatures and no screening (the naive way).
Last, a diagnosis of a continuous session (H hits a level, 33 s apart) with each impact's start
fitted, as the fitter's /fmm/diagnose_model does by default, with every refit's Jacobian by
blocks (a start position runs its own impact) against dense (every column, every impact).
Issue 8's targets: accuracy >= 95 %, one diagnosis of three 33 s impacts <= 10 s.
"""

import argparse
import functools
import statistics
import time

import numpy as np

import fmm_ros.core.diagnose.workflow as diagnose_module
from fmm_ros.core.diagnose.workflow import diagnose
from fmm_ros.core.identify.conditioning import as_conditioned
from fmm_ros.core.identify.friction import fit_model
from fmm_ros.core.physics.terms import MODEL_TERMS
from fmm_ros.core.signal.capture import capture_impacts
from fmm_ros.sim.hidden_effects import HIDDEN_EFFECTS, hidden_effect_case
from fmm_ros.sim.session import simulated_session

TARGET_ACCURACY = 0.95
TARGET_SECONDS = 10.0

SHORT = {
    'viscous_damping': 'visc',
    'stribeck': 'strib',
    'asymmetric_friction': 'asym',
    'cubic_stiffness': 'cubic',
    'velocity_offset': 'offs',
    'sensor_delay': 'delay',
    'second_mode': 'mode2',
    'none': 'none',
}


def sweep(cases: int, seed: int) -> None:
    names = list(HIDDEN_EFFECTS)
    confusion = np.zeros((len(names), len(names)), dtype=int)
    reductions, ratios, misses = [], [], []
    seconds: dict[str, list[float]] = {name: [] for name in names}
    for row, effect in enumerate(names):
        for case in range(cases):
            rng = np.random.default_rng([seed, row, case])
            session = hidden_effect_case(effect, rng)
            start = time.perf_counter()
            result = diagnose(session.records)
            seconds[effect].append(time.perf_counter() - start)
            confusion[row, names.index(result.missing_effect)] += 1
            if effect != 'none':
                ratios.append(session.ratio)
                reductions.append(1.0 - result.gap_after / result.gap_before)
            if result.missing_effect != effect:
                misses.append(
                    f'  {effect} (ratio {session.ratio:.2f}, case {case}) named '
                    f'{result.missing_effect}: {result.verdict}'
                )
        print(f'  {effect}: done', flush=True)
    width = max(len(s) for s in SHORT.values()) + 1
    print('\nconfusion matrix (rows: hidden effect, columns: named effect)')
    print(' ' * 8 + ''.join(f'{SHORT[n]:>{width}}' for n in names))
    for row, name in enumerate(names):
        print(f'{SHORT[name]:>8}' + ''.join(f'{count:>{width}}' for count in confusion[row]))
    accuracy = np.trace(confusion) / confusion.sum()
    print(
        f'\naccuracy {100 * accuracy:.1f} % of {confusion.sum()} sessions '
        f'(target >= {100 * TARGET_ACCURACY:.0f} %)'
    )
    print(
        f'hidden effects sized {min(ratios):.2f}-{max(ratios):.2f}x the velocity noise '
        'after the base fit'
    )
    print(
        f'median gap reduction where an effect was hidden: {100 * np.median(reductions):.1f} % '
        f'(smallest {100 * min(reductions):.1f} %)'
    )
    every = [value for values in seconds.values() for value in values]
    print(
        f'diagnosis time per session (three 33 s impacts): median '
        f'{statistics.median(every):.2f} s, longest {max(every):.2f} s; by hidden effect: '
        + ', '.join(
            f'{SHORT[name]} {statistics.median(values):.1f}/{max(values):.1f}'
            for name, values in seconds.items()
        )
        + ' s (median/longest)'
    )
    print('misses:' if misses else 'misses: none')
    for miss in misses:
        print(miss)


def naive_start(effect, *_args, **_kwargs):
    """Every candidate from its declared defaults: what a refit without signatures does."""
    return MODEL_TERMS[effect]()


def timing(repeats: int, seed: int) -> None:
    session = hidden_effect_case('stribeck', seed)
    diagnose(session.records)  # JIT and caches warm
    guided = []
    for _ in range(repeats):
        start = time.perf_counter()
        diagnose(session.records)
        guided.append(time.perf_counter() - start)
    original_start, original_screen = diagnose_module.start_term, diagnose_module.SCREEN_SECOND_MODE
    diagnose_module.start_term, diagnose_module.SCREEN_SECOND_MODE = naive_start, False
    try:
        start = time.perf_counter()
        naive_result = diagnose(session.records)
        naive = time.perf_counter() - start
    finally:
        diagnose_module.start_term, diagnose_module.SCREEN_SECOND_MODE = (
            original_start,
            original_screen,
        )
    guided_s = statistics.median(guided)
    print(
        f'\none diagnosis of three 33 s impacts, all {len(MODEL_TERMS)} candidates '
        f'(hidden stribeck): median {guided_s:.2f} s of {repeats} '
        f'(target <= {TARGET_SECONDS:.0f} s)'
    )
    print(
        f'naive (default starts, no screening): {naive:.2f} s, {naive / guided_s:.1f}x '
        f'slower; named {naive_result.missing_effect}'
    )


def session_timing(hits_per_level: int) -> None:
    session = simulated_session(
        hits_per_level, seed=3, force_noise_std_n=0.2, velocity_noise_std_m_s=1e-4
    )
    impacts = [
        as_conditioned(record)
        for record in capture_impacts(session.force_n, session.velocity_m_s, session.sample_rate_hz)
    ]
    seconds = {}
    for jacobian in ('blocks', 'dense'):
        diagnose_module.fit_model = functools.partial(fit_model, jacobian=jacobian)
        try:
            start = time.perf_counter()
            result = diagnose(impacts, fit_initial_position=True)
            seconds[jacobian] = time.perf_counter() - start
        finally:
            diagnose_module.fit_model = fit_model
        print(
            f'diagnosis of a {len(impacts)}-hit session, each start fitted, Jacobians '
            f'{jacobian}: {seconds[jacobian]:.1f} s (one run; named {result.missing_effect}, '
            f'mu {result.mu:.5f})'
        )
    print(f'  blocks {seconds["dense"] / seconds["blocks"]:.1f}x faster')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--cases', type=int, default=10, help='sessions per hidden effect')
    parser.add_argument('--seed', type=int, default=2019)
    parser.add_argument('--repeats', type=int, default=5, help='timing repeats')
    parser.add_argument(
        '--session-hits',
        type=int,
        default=3,
        help='hits per level of the session diagnosed with starts (0: skip)',
    )
    args = parser.parse_args()
    print(f'sweep: {args.cases} sessions per hidden effect and none, three impacts each')
    sweep(args.cases, args.seed)
    timing(args.repeats, args.seed)
    if args.session_hits:
        session_timing(args.session_hits)


if __name__ == '__main__':
    main()
