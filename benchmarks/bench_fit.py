"""Fitting speed: mu from one 33 s impact, the joint fit over three, a whole session, rig ID.

Run: .venv/bin/python benchmarks/bench_fit.py [--repeats N] [--session-hits N]

Records: the issues' lab noise (0.2 N, 1e-4 m/s) on 33 s, 10 kHz impacts at the paper's levels,
mu = 0.113. Prints medians over repeats (the machine is shared), and in the same run the same
fits with the paper's Euler integrator, compiled (integrator='euler') and written plainly in
Python (bench_physics.euler_in_python, the loop one would first write), plus scipy's
least_squares on the same residuals (what the fitter's own Levenberg-Marquardt replaces).
Then a continuous session (hits 33 s apart, each starting where friction left the last) cut
into 33 s records and fitted as the fitter service and the session report do:
fit_friction(records, fit_initial_position=True), time and tracemalloc peak, now (impulse
scales, hum and drift) and as the exact-force fit (`EXACT_FORCE`) in the same run, the latter
also with the Jacobian dense (jacobian='dense', the plain way, one run).
"""

import argparse
import dataclasses
import os
import sys
import time
import tracemalloc

import numpy as np
import scipy.optimize
from bench_physics import RATE_HZ, euler_in_python, median_s
from results_file import QUICK_HELP, recorded

from fmm_ros.constants import PAPER_LEVELS, PAPER_MU
from fmm_ros.core.identify.conditioning import condition_impact
from fmm_ros.core.identify.friction import energy_balance_mu, fit_friction, fit_model
from fmm_ros.core.identify.lsq import levenberg_marquardt
from fmm_ros.core.identify.rig import identify_rig
from fmm_ros.core.identify.spec import MU_BOUNDS
from fmm_ros.core.physics.model import simulate
from fmm_ros.core.physics.rig import FMM_RIG
from fmm_ros.core.signal.capture import capture_impacts
from fmm_ros.sim.excitation import impact_record
from fmm_ros.sim.session import simulated_session

TARGET_ONE_MS = 100.0
TARGET_JOINT_MS = 300.0
TARGET_SESSION_S = 2.0
TARGET_SESSION_MB = 600.0


def lab_record(peak_force_n, seed, mu=PAPER_MU):
    return impact_record(
        peak_force_n,
        seed,
        mu=mu,
        force_noise_std_n=0.2,
        velocity_noise_std_m_s=1e-4,
        pretrigger_s=0.05,
    )


def python_euler_fit(impact):
    """The same one-impact mu fit (same optimiser, same start) on the plain-Python Euler."""

    def residual(theta, out):
        _, velocity = euler_in_python(impact.force_n, RATE_HZ, FMM_RIG, float(theta[0]))
        np.subtract(impact.velocity_m_s, velocity, out=out)

    start = np.array([energy_balance_mu([impact])])
    return levenberg_marquardt(
        residual,
        start,
        np.array([MU_BOUNDS[0]]),
        np.array([MU_BOUNDS[1]]),
        start,
        impact.force_n.size,
    )


def scipy_least_squares_fit(impacts, fit_damping=False):
    """The same fit (mu, or mu and c) through scipy.optimize.least_squares (trf, bounds)."""
    outs = [(np.empty(i.force_n.size), np.empty(i.force_n.size)) for i in impacts]

    def residual(theta):
        rig = (
            FMM_RIG
            if not fit_damping
            else dataclasses.replace(FMM_RIG, damping_n_s_per_m=float(theta[1]))
        )
        return np.concatenate(
            [
                i.velocity_m_s
                - simulate(i.force_n, RATE_HZ, rig=rig, mu=float(theta[0]), out=out).velocity_m_s
                for i, out in zip(impacts, outs, strict=True)
            ]
        )

    start = [energy_balance_mu(impacts)] + ([FMM_RIG.damping_n_s_per_m] if fit_damping else [])
    bounds = ([MU_BOUNDS[0], 0.0][: len(start)], [MU_BOUNDS[1], 50.0][: len(start)])
    return scipy.optimize.least_squares(
        residual, start, bounds=bounds, x_scale=start, diff_step=1e-4
    )


def traced_run(function):
    """(seconds, tracemalloc peak [MB], result) of one call."""
    tracemalloc.start()
    start = time.perf_counter()
    try:
        result = function()
        seconds = time.perf_counter() - start
        peak_mb = tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()
    return seconds, peak_mb, result


EXACT_FORCE = dict(
    fit_impulse_scale=False,
    remove_mains_hum=False,
    fit_velocity_drift=False,
    judge_hit=True,
    uncertainty='blocks',
)
"""fit_friction's options of the exact-force fit, the plain fit the current one is weighed
against: measured impulse as exact, velocity as measured, the hit judged, block-sum errors."""


def session_fits(hits_per_level: int, repeats: int) -> tuple[float, float]:
    """fit_friction of a whole session with start positions: now, exact-force, dense.

    Returns the current fit's (median seconds, peak MB).
    """
    session = simulated_session(
        hits_per_level, seed=3, force_noise_std_n=0.2, velocity_noise_std_m_s=1e-4
    )
    records = capture_impacts(session.force_n, session.velocity_m_s, session.sample_rate_hz)
    del session
    samples = sum(record.force_n.size for record in records)
    print(
        f'\nA session of {len(records)} hits, 33 s records ({samples / 1e6:.1f} M samples a '
        f'channel): fit_friction(records, fit_initial_position=True), jointly (mu, each '
        "impact's start and impulse scale, hum and drift), then each impact alone"
    )

    def run(jacobian='blocks', **options):
        return fit_friction(records, fit_initial_position=True, jacobian=jacobian, **options)

    now_s = median_s(run, repeats)
    _, now_mb, now = traced_run(run)
    before_s = median_s(lambda: run(**EXACT_FORCE), repeats)
    _, before_mb, before = traced_run(lambda: run(**EXACT_FORCE))
    dense_s, dense_mb, dense = traced_run(lambda: run('dense', **EXACT_FORCE))
    print(f'  {"fit":<52} {"time":>8} {"peak":>9}   mu +- stderr')
    for label, seconds, mb, fitted in (
        (f'now, Jacobian by blocks (median of {repeats})', now_s, now_mb, now),
        (f'exact-force fit, by blocks (median of {repeats})', before_s, before_mb, before),
        ('exact-force fit, dense (one run, traced)', dense_s, dense_mb, dense),
    ):
        print(
            f'  {label:<52} {seconds:7.2f}s {mb:6.0f} MB   {fitted.mu:.6f} +- '
            f'{fitted.mu_stderr:.2g}'
        )
    joint, plain = before.joint, dense.joint
    worst = max(
        abs(a - b) / e for a, b, e in zip(joint.values, plain.values, plain.stderr, strict=True)
    )
    error_ratio = max(abs(a / b - 1.0) for a, b in zip(joint.stderr, plain.stderr, strict=True))
    print(
        f'  now {now_s / before_s:.2f}x the time of the exact-force fit; blocks '
        f'{dense_s / before_s:.0f}x faster than dense, {dense_mb / before_mb:.1f}x less memory '
        f'(largest difference {worst:.2g} standard errors in a value, {100 * error_ratio:.2g} % '
        'in a standard error)'
    )
    return now_s, now_mb


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeats', type=int, default=21)
    parser.add_argument(
        '--session-hits',
        type=int,
        default=10,
        help='hits per paper level in the session (3 levels)',
    )
    parser.add_argument('--quick', action='store_true', help=QUICK_HELP)
    args = parser.parse_args()
    if args.quick:
        args.repeats, args.session_hits = 1, 1
    repeats = args.repeats

    one = lab_record(1000.0, 1)
    three = [
        lab_record(level.peak_force_n, seed) for seed, level in enumerate(PAPER_LEVELS, start=2)
    ]
    lifted = [
        lab_record(level.peak_force_n, seed, mu=0.0)
        for seed, level in enumerate(PAPER_LEVELS, start=5)
    ]
    impact = condition_impact(one.force_n, one.velocity_m_s, RATE_HZ)
    impacts = [condition_impact(r.force_n, r.velocity_m_s, RATE_HZ) for r in three]
    for integrator in ('exact', 'euler'):  # JIT cache load kept out of the timings
        fit_model(impact, integrator=integrator)

    print(
        f'Lab records: 33 s at {RATE_HZ:g} Hz, 0.2 N and 1e-4 m/s noise, mu = {PAPER_MU}; '
        f'medians of {repeats}'
    )
    condition_s = median_s(
        lambda: condition_impact(one.force_n, one.velocity_m_s, RATE_HZ), repeats
    )
    print(f'  condition one record (baseline, gate, noise levels)     {1e3 * condition_s:7.1f} ms')

    rows = {}
    for integrator in ('exact', 'euler'):
        single = fit_model(impact, integrator=integrator)
        rows[('one', integrator)] = (
            median_s(lambda i=integrator: fit_model(impact, integrator=i), repeats),
            single.mu,
            single.evaluations,
        )
        joint = fit_model(impacts, integrator=integrator)
        rows[('joint', integrator)] = (
            median_s(lambda i=integrator: fit_model(impacts, integrator=i), repeats),
            joint.mu,
            joint.evaluations,
        )
        both = fit_model(impacts, integrator=integrator, fit_damping=True)
        rows[('joint_c', integrator)] = (
            median_s(
                lambda i=integrator: fit_model(impacts, integrator=i, fit_damping=True), repeats
            ),
            both.mu,
            both.evaluations,
        )
        full = fit_friction(impacts, integrator=integrator)
        rows[('full', integrator)] = (
            median_s(
                lambda i=integrator: fit_friction(impacts, integrator=i), max(3, repeats // 3)
            ),
            full.mu,
            None,
        )
    labels = {
        'one': 'mu, one impact',
        'joint': 'mu, three impacts jointly',
        'joint_c': 'mu and c, three impacts jointly',
        'full': 'fit_friction: joint + 3 per-impact mu',
    }
    print(f'  {"fit":<40} {"exact":>9} {"euler":>9} {"ratio":>6}   mu (exact / euler), model runs')
    for key, label in labels.items():
        exact_s, exact_mu, runs = rows[(key, 'exact')]
        euler_s, euler_mu, _ = rows[(key, 'euler')]
        print(
            f'  {label:<40} {1e3 * exact_s:7.1f}ms {1e3 * euler_s:7.1f}ms '
            f'{euler_s / exact_s:5.2f}x   {exact_mu:.5f} / {euler_mu:.5f}'
            f'{f", {runs}" if runs else ""}'
        )
    starts_s = median_s(lambda: fit_model(impacts, fit_initial_position=True), repeats)
    print(f'  mu and every impact start, three impacts                {1e3 * starts_s:7.1f} ms')
    frf_s = median_s(lambda: fit_model(impacts, misfit='frf'), repeats)
    print(f'  mu, three impacts, mobility (FRF) misfit                {1e3 * frf_s:7.1f} ms')
    end_to_end_s = median_s(
        lambda: fit_model(condition_impact(one.force_n, one.velocity_m_s, RATE_HZ)), repeats
    )
    print(f'  mu, one impact, from the raw record (condition + fit)   {1e3 * end_to_end_s:7.1f} ms')

    print('\nBaselines in the same run')
    start = time.perf_counter()
    python = python_euler_fit(impact)
    python_s = time.perf_counter() - start
    exact_one_s = rows[('one', 'exact')][0]
    print(
        f'  same fit on the paper Euler in plain Python             {python_s:7.2f} s '
        f'({python_s / exact_one_s:.0f}x; mu {python.x[0]:.5f}, {python.evaluations} runs, '
        f'one repeat)'
    )
    for label, fit_impacts, damping, ours_s in (
        ('mu, one impact', [impact], False, exact_one_s),
        ('mu and c, three impacts', impacts, True, rows[('joint_c', 'exact')][0]),
    ):
        least_squares_s = median_s(
            lambda f=fit_impacts, d=damping: scipy_least_squares_fit(f, d), max(3, repeats // 3)
        )
        solution = scipy_least_squares_fit(fit_impacts, damping)
        print(
            f'  scipy least_squares, {label:<24}           {1e3 * least_squares_s:7.1f} ms '
            f'({least_squares_s / ours_s:.1f}x ours; mu {solution.x[0]:.5f}, '
            f'{solution.nfev} evaluations + Jacobians, no standard errors)'
        )
    threads = os.environ.get('OPENBLAS_NUM_THREADS', 'default')
    print(
        f'  (OPENBLAS_NUM_THREADS={threads}: scipy does its Jacobian products in BLAS, whose '
        f'threads\n   slow it badly when the shared cores are busy; the fitter uses einsum)'
    )

    print('\nRig identification (mu = 0)')
    rig_s = median_s(lambda: identify_rig(lifted), max(3, repeats // 3))
    rig = identify_rig(lifted)
    print(
        f'  m, c, k from three lifted impacts                       {1e3 * rig_s:7.1f} ms '
        f'(m {rig.mass_kg:.4f} kg, c {rig.damping_n_s_per_m:.4f} N*s/m, '
        f'k {rig.stiffness_n_per_m:.2f} N/m)'
    )

    session_s, session_mb = session_fits(args.session_hits, max(3, repeats // 3))

    one_ms = 1e3 * rows[('one', 'exact')][0]
    joint_ms = 1e3 * rows[('joint_c', 'exact')][0]
    session_met = session_s <= TARGET_SESSION_S and session_mb <= TARGET_SESSION_MB
    print(
        f'\n=> mu from one impact {one_ms:.1f} ms (target <= {TARGET_ONE_MS:g} ms: '
        f'{verdict(one_ms <= TARGET_ONE_MS)}); joint fit over three (mu and c) '
        f'{joint_ms:.1f} ms (target <= {TARGET_JOINT_MS:g} ms: '
        f'{verdict(joint_ms <= TARGET_JOINT_MS)}); the {3 * args.session_hits}-hit session '
        f'with starts {session_s:.2f} s and {session_mb:.0f} MB (targets <= '
        f'{TARGET_SESSION_S:g} s, <= {TARGET_SESSION_MB:g} MB: {verdict(session_met)})'
    )


def verdict(met: bool) -> str:
    return 'met' if met else 'MISSED'


if __name__ == '__main__':
    with recorded('bench_fit', quick='--quick' in sys.argv):
        main()
