"""Offline analysis of a 30-hit session bag: 16.5 min of two 10 kHz channels.

The session (10 hits at each of the paper's levels, 33 s apart, simulated by the physics
core and written as the recorder would) is replayed as `fmm replay` does: a clean bag's
channels found in the file (its chunks' checksums verified on a second thread meanwhile),
copied out and captured in blocks, each record analysed as it completes, on as many
threads as there are cores (`available_threads`, printed) while the capture goes on,
levels summarized.
Against it, in the same run and interleaved (each repeat runs every row once, medians
reported): the same replay on one thread, the replay batch by batch (every batch
decoded and fed to the capture one by one), the bare read of the same file (the mcap
library iterating its messages, nothing decoded: the floor a one-threaded replay cannot
beat), a naive reader that decodes every message into per-sample Python lists, and the
parts of the replay alone, on one thread (down to the three DFTs of each 33 s record, which
the analysis cannot go below while its FRF is the whole record's). Also the replay with
each faster analysis step swapped back for the numpy it replaced
(`test/reference_analysis.py`: the same results, the analysis as it was before its kernels),
a campaign session's share of the same work (its bag read by `read_inputs`, its records
analysed by `workflows.session.analyse`), on the threads and on one. And the whole process a
user waits for: fresh `fmm replay BAG` processes (start-up, imports, the numba cache load and
exit included), against a fresh `python -c pass` and the in-process replay above, one of each
per repeat; their bytecode is cached (in a temporary `PYTHONPYCACHEPREFIX`, warmed first) as
an installed package has it, whatever PYTHONDONTWRITEBYTECODE says here (--quick: as it says).
The process keeps freed memory for reuse as the `fmm` command does (`fmm_ros.core.memory`), so
every row runs under the allocator `fmm replay` runs under.

    .venv/bin/python benchmarks/bench_replay.py [--repeats 5] [--quick]
"""

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import scipy.fft
from mcap.reader import make_reader
from results_file import QUICK_HELP, recorded

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))
from reference_analysis import numpy_steps  # noqa: E402
from rosbags.rosbag2 import Reader

from fmm_ros.constants import FORCE_TOPIC, VELOCITY_TOPIC
from fmm_ros.core._threads import available_threads, thread_map
from fmm_ros.core.memory import keep_freed_memory
from fmm_ros.core.signal.analysis import AnalysisConfig, analyze_impact, paper_levels, summarize
from fmm_ros.core.signal.capture import DEFAULT_CAPTURE, capture_impacts
from fmm_ros.io.bags import SAMPLE_BATCH, BagReader, fmm_typestore
from fmm_ros.sim.session import simulated_session, write_session_bag
from fmm_ros.workflows.inputs import InputOptions, read_inputs
from fmm_ros.workflows.replay import (
    WHOLE_BLOCK_SAMPLES,
    bag_impact_records,
    capture_records,
    replay_bag,
)
from fmm_ros.workflows.session import analyse

ROOT = Path(__file__).resolve().parents[1]
TARGET_X = 1500.0  # times real time
TARGET_PROCESS_X = 1000.0  # times real time, the whole `fmm replay` process
TARGET_OF_BARE = 1.5  # replay time over the bare read's
ANALYSIS = AnalysisConfig(levels=paper_levels())
THREADS = available_threads()
REPLAY = f'replay (fmm replay), {THREADS} threads'
ONE_THREAD = 'replay on one thread'
BEFORE = 'replay batch by batch (decode, then capture)'
NUMPY = f'replay, analysis steps as numpy, {THREADS} threads'
BARE = 'bare read: mcap library, every message'
NAIVE = 'naive: samples via Python lists, then same'
CAMPAIGN = f'campaign session: read_inputs + analyse, {THREADS} threads'
CAMPAIGN_ONE = 'campaign session, one thread'
DFTS_ONE = '    of which: their DFTs (3 a record)'
DFTS_THREADED = f'    the same DFTs on {THREADS} threads (ceiling)'
PROCESS = 'whole process: fresh `fmm replay BAG`'
PASS = '  against: fresh `python -c pass`'
FMM_SCRIPT = 'import sys; from fmm_ros.cli import main; sys.exit(main())'  # the console script


def fresh_process(command: list[str], env: dict[str, str]) -> tuple[float, float]:
    """Wall and processor time [s] of one fresh process running command (output discarded)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(
        command, env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
    return wall, cpu


def replay(bag: Path) -> int:
    return len(replay_bag(bag, DEFAULT_CAPTURE, ANALYSIS).results)


def replay_one_thread(bag: Path) -> int:
    return len(replay_bag(bag, DEFAULT_CAPTURE, ANALYSIS, threads=1).results)


def campaign_session(threads: int) -> Callable[[Path], int]:
    """What a campaign session does before its fit: its bag's records, then their analysis."""

    def run(bag: Path) -> int:
        read = read_inputs([bag], InputOptions(capture=DEFAULT_CAPTURE))
        return len(analyse(read.records, DEFAULT_CAPTURE, ANALYSIS, threads=threads).impacts)

    return run


def replay_numpy_steps(bag: Path) -> int:
    """The replay with every faster analysis step run as its numpy definition."""
    with numpy_steps():
        return replay(bag)


def read_whole(bag: Path) -> int:
    with BagReader(bag) as reader:
        whole = reader.channel_arrays()
        return sum(f.size + v.size for _, f, v in whole.blocks(WHOLE_BLOCK_SAMPLES))


def capture_only(bag: Path) -> int:
    return len(bag_impact_records(bag, DEFAULT_CAPTURE)[0])


def analysis_only(records: list) -> Callable[[Path], int]:
    def run(_: Path) -> int:
        for k, record in enumerate(records):
            analyze_impact(record, DEFAULT_CAPTURE, ANALYSIS, impact_id=k)
        return len(records)

    return run


def dfts_only(records: list, threads: int = 1) -> Callable[[Path], int]:
    """The three DFTs analysis takes of each record (force, response, the pulse alone), alone.

    The floor of the analysis as it stands: the paper's FRF is the DFT of the whole 33 s
    record, so a record costs three 330,000-point transforms whatever else is made faster.
    On several threads (a record each, as replay shares them out): work that never holds the
    GIL, so its gain is what the machine grants threads right now, the threaded replay's
    ceiling.
    """

    def three(record) -> None:
        for samples in (record.force_n, record.velocity_m_s, record.force_n):
            scipy.fft.rfft(samples, n=record.window_samples)

    def run(_: Path) -> int:
        return len(thread_map(three, records, threads))

    return run


def before(bag: Path) -> int:
    """Replay as it ran before: each batch decoded and fed (on_batch keeps it batch by batch)."""
    results = []
    with BagReader(bag, strict=False) as reader:
        for record in capture_records(reader, reuse_buffers=True, on_batch=lambda _: None):
            result = analyze_impact(record, DEFAULT_CAPTURE, ANALYSIS, impact_id=len(results))
            results.append(result)
    summarize(results, ANALYSIS)
    return len(results)


def read_batches(bag: Path) -> int:
    with BagReader(bag) as reader:
        return sum(len(batch.samples) for batch in reader.sample_batches())


def bare(bag: Path) -> int:
    """Every message's bytes, as the mcap library hands them out (nothing decoded)."""
    size = 0
    with next(bag.glob('*.mcap')).open('rb') as stream:
        for _, _, message in make_reader(stream).iter_messages():
            size += len(message.data)
    return size


def naive(bag: Path) -> int:
    """Every sample through a Python list, then the whole arrays into capture and analysis."""
    store = fmm_typestore()
    samples: dict[str, list[float]] = {FORCE_TOPIC: [], VELOCITY_TOPIC: []}  # relative names
    rate = 0.0
    with Reader(bag) as reader:
        for connection, _, data in reader.messages():
            message = store.deserialize_cdr(data, SAMPLE_BATCH)
            rate = message.sample_rate_hz
            for value in message.samples:
                samples[connection.topic.lstrip('/')].append(float(value))
    records = capture_impacts(
        np.array(samples[FORCE_TOPIC]), np.array(samples[VELOCITY_TOPIC]), rate, DEFAULT_CAPTURE
    )
    results = [
        analyze_impact(record, DEFAULT_CAPTURE, ANALYSIS, impact_id=k)
        for k, record in enumerate(records)
    ]
    summarize(results, ANALYSIS)
    return len(results)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeats', type=int, default=5)
    parser.add_argument('--quick', action='store_true', help=QUICK_HELP)
    args = parser.parse_args()
    hits_per_level, repeats = (1, 1) if args.quick else (10, args.repeats)
    keep_freed_memory()  # as `fmm` does

    session = simulated_session(hits_per_level)
    work = Path(tempfile.mkdtemp(prefix='bench_replay_'))
    try:
        bag = write_session_bag(work / 'session', session)
        size_mb = sum(f.stat().st_size for f in bag.iterdir()) / 1e6
        records = bag_impact_records(bag, DEFAULT_CAPTURE)[0]
        campaign = campaign_session(THREADS)
        rows: dict[str, Callable[[Path], int]] = {
            REPLAY: replay,
            ONE_THREAD: replay_one_thread,
            '  of which: read (channel blocks)': read_whole,
            '  of which: read and capture': capture_only,
            '  of which: analyse the records': analysis_only(records),
            DFTS_ONE: dfts_only(records),
            DFTS_THREADED: dfts_only(records, THREADS),
            NUMPY: replay_numpy_steps,
            BEFORE: before,
            '  of which: read batches only': read_batches,
            BARE: bare,
            NAIVE: naive,
            CAMPAIGN: campaign,
            CAMPAIGN_ONE: campaign_session(1),
        }
        # Fresh processes import this checkout's fmm_ros (the one timed here), bytecode cached.
        env = dict(os.environ)
        if not args.quick:  # (a quick run skips the warm-up, which compiles every module)
            env.pop('PYTHONDONTWRITEBYTECODE', None)
            env['PYTHONPYCACHEPREFIX'] = str(work / 'pycache')
        env['PYTHONPATH'] = os.pathsep.join(filter(None, (str(ROOT), env.get('PYTHONPATH'))))
        processes = {
            PROCESS: [sys.executable, '-c', FMM_SCRIPT, 'replay', str(bag)],
            PASS: [sys.executable, '-c', 'pass'],
        }
        for command in processes.values() if not args.quick else ():  # warm up: bytecode written
            fresh_process(command, env)
        for run in rows.values() if not args.quick else ():  # warm up: compile, fault in
            run(bag)
        times: dict[str, list[float]] = {name: [] for name in (*rows, *processes)}
        replay_cpu: list[float] = []  # processor seconds of each threaded replay
        process_cpu: dict[str, list[float]] = {name: [] for name in processes}
        for _ in range(max(repeats, 1 if args.quick else 5)):  # interleaved: the same load
            for name, command in processes.items():
                wall, cpu = fresh_process(command, env)
                times[name].append(wall)
                process_cpu[name].append(cpu)
            if len(times[REPLAY]) == repeats:
                continue  # more fresh processes than repeats: at least five of them
            for name, run in rows.items():
                cpu = time.process_time()
                start = time.perf_counter()
                value = run(bag)
                times[name].append(time.perf_counter() - start)
                if name == REPLAY:
                    replay_cpu.append(time.process_time() - cpu)
                if run in (replay, replay_one_thread, replay_numpy_steps, before, naive, campaign):
                    assert value == len(session.hit_levels), (name, value)
        print(
            f'session: {len(session.hit_levels)} hits, {session.duration_s:.1f} s '
            f'({session.duration_s / 60:.1f} min) of two {session.sample_rate_hz / 1e3:g} kHz '
            f'channels, bag {size_mb:.0f} MB; median of {repeats} interleaved runs\n'
        )
        print(f'{"":50s} {"s":>7s} {"x real time":>12s}')
        seconds = {name: statistics.median(values) for name, values in times.items()}
        for name, value in seconds.items():
            if name not in processes:
                print(f'{name:50s} {value:7.3f} {session.duration_s / value:12.0f}')
        print(
            f'\n{"fresh processes (median of " + str(len(times[PASS])) + ")":50s} {"s":>7s} '
            f'{"x real time":>12s} {"processor s":>12s}'
        )
        for name in processes:
            print(
                f'{name:50s} {seconds[name]:7.3f} {session.duration_s / seconds[name]:12.0f} '
                f'{statistics.median(process_cpu[name]):12.3f}'
            )
        ours = seconds[REPLAY]
        whole = seconds[PROCESS]
        whole_speed = session.duration_s / whole
        cpu_of = {name: statistics.median(values) for name, values in process_cpu.items()}
        print(
            f'\nwhole process: {whole_speed:.0f}x real time, {whole:.3f} s (target >= '
            f'{TARGET_PROCESS_X:.0f}x, <= {session.duration_s / TARGET_PROCESS_X:.2f} s: '
            f'{"met" if whole_speed >= TARGET_PROCESS_X else "NOT met"}), '
            f'{cpu_of[PROCESS]:.3f} s of processor time; the in-process replay '
            f'{ours:.3f} s ({statistics.median(replay_cpu):.3f} s processor), so start-up and '
            f'exit {whole - ours:.3f} s ({cpu_of[PROCESS] - statistics.median(replay_cpu):.3f} s '
            'processor, the figure a loaded machine distorts least), '
            f'{(whole - ours) / seconds[PASS]:.1f}x a bare '
            f'`python -c pass` ({seconds[PASS]:.3f} s, {cpu_of[PASS]:.3f} s processor)'
        )
        speed = session.duration_s / ours
        of_bare = ours / seconds[BARE]
        print(
            f'\nreplay on {THREADS} threads: {speed:.0f}x real time (target >= {TARGET_X:.0f}x: '
            f'{"met" if speed >= TARGET_X else "NOT met"}); {of_bare:.2f}x the bare read '
            f'(target <= {TARGET_OF_BARE:g}x: {"met" if of_bare <= TARGET_OF_BARE else "NOT met"})'
        )
        one = seconds[ONE_THREAD]
        ceiling = seconds[DFTS_ONE] / seconds[DFTS_THREADED]
        print(
            f'on one thread: {session.duration_s / one:.0f}x real time, {one / seconds[BARE]:.2f}x '
            f'the bare read; the threads make it {one / ours:.2f}x faster, with '
            f'{statistics.median(replay_cpu) / ours:.2f} cores busy on average (processor '
            f'over wall time)\nceiling: the DFTs alone gain {ceiling:.2f}x on {THREADS} threads '
            '(what the machine grants threads in this run)'
        )
        print(
            f'{seconds[NUMPY] / ours:.2f}x faster than with the numpy analysis steps '
            f'({session.duration_s / seconds[NUMPY]:.0f}x real time, '
            f'{seconds[NUMPY] / seconds[BARE]:.2f}x the bare read)'
        )
        print(
            f'{seconds[BEFORE] / ours:.1f}x faster than the replay batch by batch, '
            f'{seconds[NAIVE] / ours:.1f}x faster than the naive reader'
        )
        print(
            f'campaign session (read and analysis): {seconds[CAMPAIGN]:.3f} s on {THREADS} '
            f'threads, {seconds[CAMPAIGN_ONE]:.3f} s on one '
            f'({seconds[CAMPAIGN_ONE] / seconds[CAMPAIGN]:.2f}x)'
        )
    finally:
        shutil.rmtree(work)
    return 0


if __name__ == '__main__':
    with recorded('bench_replay', quick='--quick' in sys.argv):
        raise SystemExit(main())
