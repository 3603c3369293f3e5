"""Campaign: serial against Dask on 2 workers, per-session cost, scaling, honest statistics.

Run: .venv/bin/python benchmarks/bench_campaign.py [--sessions-per-condition 4] [--hits 10]
     [--workers 2] [--campaigns 2000] [--keep DIR] [--quick]

--quick (CI: every step still runs, in about a minute): one session a condition of one hit,
every Dask run on one cluster started once, no ceiling, 20 campaigns for the statistics.

1. A generated campaign (`fmm_ros.sim.campaign`): lubricants A (mu 0.113), B (0.101) and
   C (0.113, no real difference from A) x normal forces 6.67 and 9.81 N x 4 sessions, 10 hits
   each at the paper's levels, 33 s apart (the paper's records), mu rising 0.001 per N, and
   each session's plant mu drawn about its condition's with a 0.002 standard deviation.
2. Its sessions in this process one after the other (`--serial`), then on a LocalCluster of 2
   worker processes (start included, and apart), on such a cluster already running (as a
   lab's `--scheduler ADDRESS` finds it), then again from the cache. Per-session cost
   from the serial run; the measured speed-up gives the scaling model: sessions per hour per
   core and what 1,000 sessions cost on N workers. Target: >= 1.7x on 2 cores.
3. Correctness on it: each session's mu within 1 % of its plant, the true differences and the
   load slope inside their intervals, C not declared different from A.
4. The statistics' honesty over many campaigns of session mu drawn from a random-effects
   model (no physics, so thousands are cheap): coverage of the 95 % intervals of the
   lubricant differences and how often C is declared different from A, for the model used
   (REML + Knapp-Hartung) and the naive ones in the same run: a fixed-effect test that
   takes each session's fit error as its whole uncertainty, and DerSimonian-Laird with
   normal (z) intervals.
"""

import argparse
import contextlib
import dataclasses
import math
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import scipy.stats

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))
from campaign_sessions import COLUMNS, LOADS_N, LUBRICANTS, random_effects_campaign  # noqa: E402
from results_file import QUICK_HELP, recorded

from fmm_ros.campaign.cache import session_key
from fmm_ros.campaign.compare import compare_sessions
from fmm_ros.campaign.results import run_campaign
from fmm_ros.campaign.stats import meta_regression
from fmm_ros.campaign.table import read_campaign_table
from fmm_ros.campaign.tasks import SERIAL, local_cluster, run_cached_session, run_sessions
from fmm_ros.core.signal.analysis import AnalysisConfig, paper_levels
from fmm_ros.sim.campaign import simulated_campaign
from fmm_ros.workflows.session import SessionOptions

LOAD_SLOPE_PER_N = 0.001
SESSION_SCATTER = 0.002
TARGET_SPEEDUP = 1.7
SETTINGS = SessionOptions(analysis=AnalysisConfig(levels=paper_levels()))
WORKER_COUNTS = (1, 2, 8, 32, 128)


def timed(step):
    clock = time.perf_counter()
    value = step()
    return value, time.perf_counter() - clock


def _numpy_work(_: int) -> float:
    """A fixed amount of array arithmetic (no I/O, no Dask): the ceiling's unit of work."""
    values = np.random.default_rng(0).normal(size=330_000)
    for _ in range(300):
        values = np.tanh(np.cumsum(values) * 1e-3) + 0.5 * values
    return float(values[0])


def machine_ceiling(workers: int, tasks: int = 8) -> float:
    """Speed-up the machine grants right now to `workers` plain processes over one.

    On cores shared with other jobs (and a share fixed per job), more processes of ours need
    not mean more processor time for us; this is what any parallel run could reach.
    """
    import multiprocessing

    times = []
    for processes in (1, workers):
        with multiprocessing.get_context('spawn').Pool(processes) as pool:
            pool.map(_numpy_work, range(processes))  # started and warm
            times.append(timed(lambda pool=pool: pool.map(_numpy_work, range(tasks)))[1])
    return times[0] / times[1]


def speed(folder: Path, args) -> None:
    """The campaign's runs, timed; quick: every Dask run on one cluster started once."""
    if not args.quick:
        measure(folder, args, None)
        return
    # Each Dask cluster costs a start (seconds, and half a minute on a busy machine): the
    # quick run, which only shows that every step still runs, starts one.
    with contextlib.ExitStack() as stack:
        cluster, start_s = timed(lambda: stack.enter_context(local_cluster(args.workers)))
        measure(folder, args, (cluster.scheduler_address, start_s))


def measure(folder: Path, args, shared: tuple[str, float] | None) -> None:
    """Serial against Dask, the cache, per-session cost, scaling and correctness.

    shared: (address, start seconds) of one running cluster every Dask run takes (quick;
    the ceiling is then left out), or None: each run starts its own, as a campaign does.
    """
    print(
        f'campaign: {len(LUBRICANTS)} lubricants x {len(LOADS_N)} loads x '
        f'{args.sessions_per_condition} sessions, {args.hits} hits of 33 s each'
    )
    generated, generate_s = timed(
        lambda: simulated_campaign(
            folder,
            LUBRICANTS,
            LOADS_N,
            sessions_per_condition=args.sessions_per_condition,
            hits=args.hits,
            session_scatter=SESSION_SCATTER,
            load_slope_per_n=LOAD_SLOPE_PER_N,
            seed=args.seed,
        )
    )
    table = read_campaign_table(generated.table)
    sessions = len(table.sessions)
    print(f'generated {sessions} session bags in {generate_s:.1f} s')
    print(f'load average before the runs: {os.getloadavg()[0]:.2f} (2 cores shared)')
    by, trend = ('lubricant', 'normal_force_n'), ('normal_force_n',)

    def campaign(scheduler, cache):
        return run_campaign(
            table,
            SETTINGS,
            by=by,
            trend=trend,
            scheduler=scheduler,
            workers=args.workers,
            cache_dir=cache,
        )

    # Serial and parallel runs alternate, so a change in the other jobs' load falls on both;
    # each is reported, and the speed-up of the pair with the least load.
    rows, pairs = [], []
    own = shared[0] if shared else None  # the scheduler of a run that would start its own
    for _ in range(args.repeats):
        if not shared:
            rows.append(
                (
                    f'  ceiling: plain numpy work in {args.workers} processes',
                    None,
                    machine_ceiling(args.workers),
                )
            )
        serial_load = os.getloadavg()[0]
        serial, serial_s = timed(lambda: campaign(SERIAL, None))
        rows.append((f'serial, in this process (load {serial_load:.1f})', serial_s, None))
        if not shared:
            parallel_load = os.getloadavg()[0]
            parallel, parallel_s = timed(lambda: campaign(None, None))
            rows.append(
                (
                    f'Dask, {args.workers} workers, start included (load {parallel_load:.1f})',
                    parallel_s,
                    serial_s / parallel_s,
                )
            )
        # The same graph on a cluster already running (a lab's `--scheduler ADDRESS`): its
        # workers started and warmed by one session each, outside the time.
        with contextlib.ExitStack() as stack:
            address = (
                shared[0]
                if shared
                else stack.enter_context(local_cluster(args.workers)).scheduler_address
            )
            run_sessions(
                [s.spec for s in table.sessions[: args.workers]], SETTINGS, scheduler=address
            )
            running_load = os.getloadavg()[0]
            running, running_s = timed(lambda address=address: campaign(address, None))
        rows.append(
            (
                f'Dask, {args.workers} workers already running (load {running_load:.1f})',
                running_s,
                serial_s / running_s,
            )
        )
        if shared:  # the one Dask run stands for both
            parallel, parallel_s, parallel_load = running, running_s, running_load
        pairs.append(
            (serial_load + parallel_load, serial, serial_s, parallel, parallel_s, running_s)
        )
    _, serial, serial_s, parallel, parallel_s, running_s = min(pairs, key=lambda pair: pair[0])
    start_s = (
        shared[1] if shared else timed(lambda: run_sessions([], SETTINGS, workers=args.workers))[1]
    )
    _, cold_s = timed(lambda: campaign(own, folder / 'cache'))
    _, cached_s = timed(lambda: campaign(own, folder / 'cache'))
    speedup = serial_s / parallel_s
    print(f'\n{"run (no cache unless said)":<52} {"wall s":>7} {"speed-up":>9}')
    for label, seconds, ratio in rows:
        wall = f'{seconds:>7.1f}' if seconds is not None else ' ' * 7
        print(f'{label:<52} {wall} {ratio or 1.0:>9.2f}')
    print(f'{"Dask cluster start and stop alone":<52} {start_s:>7.1f}')
    print(f'{"Dask with the cache, first run (hashing every bag)":<52} {cold_s:>7.1f}')
    print(f'{"Dask with the cache, rerun (every session cached)":<52} {cached_s:>7.1f}')
    print(
        f'speed-up of the least loaded pair: {speedup:.2f} with the cluster start, '
        f'{serial_s / running_s:.2f} on a running cluster (target >= {TARGET_SPEEDUP} on 2 cores)'
    )
    key_s = statistics.median(
        timed(lambda s=s: session_key(s.spec, SETTINGS))[1] for s in table.sessions[:3]
    )
    wall = [sum(r.seconds.values()) for r in serial.results]
    steps = {
        step: statistics.median(r.seconds[step] for r in serial.results)
        for step in serial.results[0].seconds
    }
    cpu_serial = statistics.median(r.cpu_seconds for r in serial.results)
    cpu_workers = statistics.median(r.cpu_seconds for r in parallel.results)
    print(
        f'\nper session ({args.hits} hits), serial: wall median {statistics.median(wall):.2f} s '
        f'({min(wall):.2f}-{max(wall):.2f}); '
        + ', '.join(f'{step} {value:.2f} s' for step, value in steps.items())
        + f'; processor time {cpu_serial:.2f} s serial, {cpu_workers:.2f} s in a Dask worker;'
        f' hashing its bag for the cache key {key_s:.2f} s'
    )
    diagnosed = timed(
        lambda: run_cached_session(
            table.sessions[0].spec,
            dataclasses.replace(SETTINGS, diagnose=True),
            None,
        )
    )[0]
    print(
        f'one session diagnosed as well (--diagnose): diagnosis '
        f'{diagnosed.seconds["process"] - steps["process"]:.1f} s more than without '
        f'(analysis, fit and model {steps["process"]:.2f} s)'
    )
    scaling(
        serial_s / sessions, cpu_serial, cpu_workers, speedup / args.workers, start_s, args.workers
    )
    correctness(serial, generated)


def scaling(
    wall_per_session: float,
    cpu_serial: float,
    cpu_worker: float,
    efficiency: float,
    start_s: float,
    workers: int,
) -> None:
    """Sessions per hour per core, and 1,000 sessions on N workers.

    On cores of their own: the processor time a session takes serially, at the efficiency
    its processor time in a worker gives (cpu_serial / cpu_worker). As loaded here: the
    serial wall time a session at the measured wall-time efficiency.
    """
    cpu_efficiency = min(cpu_serial / cpu_worker, 1.0)
    print(
        f'\nscaling model: a session costs {cpu_serial:.2f} s of processor time '
        f'({3600 / cpu_serial:.0f} sessions an hour on a core of its own), {cpu_worker:.2f} s in '
        f'a worker (efficiency {cpu_efficiency:.2f}); it took {wall_per_session:.2f} s of wall '
        f'time serially on the shared machine ({3600 / wall_per_session:.0f} an hour), wall-time '
        f'efficiency on {workers} workers {efficiency:.2f}; cluster start {start_s:.1f} s'
    )
    print(f'{"workers":>8} {"1,000 sessions (cores of their own)":>36} {"(as loaded here)":>17}')
    for count in WORKER_COUNTS:
        own = start_s + 1000 * cpu_serial / (count * cpu_efficiency)
        loaded = start_s + 1000 * wall_per_session / (count * min(efficiency, 1.0))
        print(f'{count:>8} {own / 60:>32.1f} min {loaded / 60:>13.1f} min')


def correctness(campaign, generated) -> None:
    errors = [
        abs(result.mu / generated.session_mu[session.session_id] - 1)
        for session, result in zip(campaign.table.sessions, campaign.results, strict=True)
    ]
    print(
        f'\nsessions fitted: {sum(r.ok for r in campaign.results)} of {len(errors)}; '
        f'largest |mu / plant mu - 1|: {100 * max(errors):.3f} % (target <= 1 %)'
    )
    comparison = campaign.comparison
    for difference in comparison.differences:
        if difference.column != 'lubricant' or not difference.averaged:
            continue
        truth = LUBRICANTS[difference.level] - LUBRICANTS[difference.reference]
        c = difference.estimate
        print(
            f'{difference.level} - {difference.reference}: {c.estimate:+.5f} '
            f'[{c.ci_low:+.5f}, {c.ci_high:+.5f}], truth {truth:+.5f} '
            f'{"inside" if c.ci_low <= truth <= c.ci_high else "OUTSIDE"}; '
            f'{"declared different" if difference.different else "not declared different"}'
        )
    for trend in comparison.trends:
        c = trend.slope
        print(
            f'slope against {trend.column} ({trend.group}): {c.estimate:+.5f} '
            f'[{c.ci_low:+.5f}, {c.ci_high:+.5f}] per {trend.unit}, truth {LOAD_SLOPE_PER_N:+.5f} '
            f'{"inside" if c.ci_low <= LOAD_SLOPE_PER_N <= c.ci_high else "OUTSIDE"}'
        )
    print('verdict:')
    for verdict in comparison.verdicts:
        print(f'  {verdict}')


# -- calibration ------------------------------------------------------------------------------


def naive_contrast(sessions, method: str):
    """C - A and B - A averaged over loads, with a two-sided 95 % z interval and p.

    'fixed': weights 1/v_i and the fits' errors as the whole uncertainty; 'dl': DerSimonian-
    Laird tau^2 and z intervals (no Knapp-Hartung).
    """
    cells = sorted({(s.conditions['lubricant'], s.conditions['normal_force_n']) for s in sessions})
    design = np.array(
        [
            [cell == (s.conditions['lubricant'], s.conditions['normal_force_n']) for cell in cells]
            for s in sessions
        ],
        dtype=float,
    )
    y = np.array([s.mu for s in sessions])
    v = np.array([s.variance for s in sessions])
    if method == 'fixed':
        w = 1.0 / v
        cov = np.linalg.inv(design.T @ (w[:, None] * design))
        beta = cov @ (design.T @ (w * y))
    else:
        fit = meta_regression(y, v, design, tau2_method='dl', knapp_hartung_floor=False)
        beta, cov = fit.coefficients, fit.model_covariance
    out = {}
    for level in ('B', 'C'):
        weights = np.array([(lub == level) - (lub == 'A') for lub, _ in cells], dtype=float) / len(
            LOADS_N
        )
        estimate, stderr = weights @ beta, math.sqrt(weights @ cov @ weights)
        z = scipy.stats.norm.ppf(0.975)
        p = 2 * scipy.stats.norm.sf(abs(estimate / stderr))
        out[level] = (estimate - z * stderr, estimate + z * stderr, p)
    return out


def calibration(campaigns: int, seed: int) -> None:
    print(
        f'\nstatistics over {campaigns} simulated campaigns a row (session mu from a '
        'random-effects model): coverage of the 95 % intervals of B - A and C - A (averaged over '
        'loads), and how often C (no real difference) is declared different from A'
    )
    print(f'{"scenario":<40} {"method":<34} {"coverage":>9} {"C vs A declared":>16}')
    scenarios = (
        ('4 sessions/condition, tau 0.002', 4, SESSION_SCATTER, 2e-5),
        ('2 sessions/condition, tau 0.002', 2, SESSION_SCATTER, 2e-5),
        ('4 sessions/condition, no scatter', 4, 0.0, 5e-4),
    )
    truth = {level: LUBRICANTS[level] - LUBRICANTS['A'] for level in ('B', 'C')}
    for name, per_condition, tau, sigma in scenarios:
        rng = np.random.default_rng(seed)
        tallies = {key: ([], []) for key in ('model', 'fixed', 'dl')}
        for _ in range(campaigns):
            sessions = random_effects_campaign(rng, per_condition, tau, sigma)
            comparison = compare_sessions(sessions, COLUMNS, ('lubricant', 'normal_force_n'))
            for d in comparison.differences:
                if d.column == 'lubricant' and d.averaged and d.reference == 'A':
                    c = d.estimate
                    tallies['model'][0].append(c.ci_low <= truth[d.level] <= c.ci_high)
                    if d.level == 'C':
                        tallies['model'][1].append(d.different)
            for method in ('fixed', 'dl'):
                for level, (low, high, p) in naive_contrast(sessions, method).items():
                    tallies[method][0].append(low <= truth[level] <= high)
                    if level == 'C':
                        tallies[method][1].append(p < 0.05)
        labels = {
            'model': 'REML + Knapp-Hartung, Holm (used)',
            'fixed': 'naive: fit errors only, z',
            'dl': 'naive: DerSimonian-Laird, z',
        }
        for key, (covered, declared) in tallies.items():
            print(
                f'{name:<40} {labels[key]:<34} {100 * np.mean(covered):>8.1f}% '
                f'{100 * np.mean(declared):>15.1f}%'
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--sessions-per-condition', type=int, default=4)
    parser.add_argument('--hits', type=int, default=10)
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--repeats', type=int, default=2, help='serial/Dask pairs')
    parser.add_argument('--campaigns', type=int, default=2000)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--keep', type=Path, help='generate the campaign here and keep it')
    parser.add_argument('--quick', action='store_true', help=QUICK_HELP)
    args = parser.parse_args()
    if args.quick:
        args.sessions_per_condition, args.hits, args.repeats, args.campaigns = 1, 1, 1, 20
    if args.keep:
        speed(args.keep, args)
    else:
        with tempfile.TemporaryDirectory(prefix='bench_campaign_') as folder:
            speed(Path(folder), args)
    calibration(args.campaigns, args.seed)


if __name__ == '__main__':
    with recorded('bench_campaign', quick='--quick' in sys.argv):
        main()
