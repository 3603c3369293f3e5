"""Offline analysis of a 30-hit session bag: 16.5 min of two 10 kHz channels (issue 7: >= 200x).

The session (10 hits at each of the paper's levels, 33 s apart, simulated by the physics
core and written as the recorder would) is replayed as `fmm replay` does: every recorded
batch fed to the analyzer's capture in order, each record analysed, levels summarized.
Against it, in the same run: a naive reader that decodes every message into per-sample
Python lists before the same capture and analysis, and the parts of the replay alone.

    .venv/bin/python benchmarks/bench_replay.py [--repeats 3]
"""

import argparse
import shutil
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader

from fmm_ros.constants import FORCE_TOPIC, VELOCITY_TOPIC
from fmm_ros.core.signal.analysis import AnalysisConfig, analyze_impact, paper_levels, summarize
from fmm_ros.core.signal.capture import DEFAULT_CAPTURE, capture_impacts
from fmm_ros.io.bags import SAMPLE_BATCH, BagReader, fmm_typestore
from fmm_ros.sim.session import simulated_session, write_session_bag
from fmm_ros.workflows.replay import capture_records, replay_bag

TARGET = 200.0
ANALYSIS = AnalysisConfig(levels=paper_levels())


def replay(bag: Path) -> int:
    return len(replay_bag(bag, DEFAULT_CAPTURE, ANALYSIS).results)


def read_only(bag: Path) -> int:
    with BagReader(bag) as reader:
        return sum(len(batch.samples) for batch in reader.sample_batches())


def read_and_capture(bag: Path) -> int:
    with BagReader(bag) as reader:
        return sum(1 for _ in capture_records(reader, reuse_buffers=True))


def naive(bag: Path) -> int:
    """Every sample through a Python list, then the whole arrays into capture and analysis."""
    store = fmm_typestore()
    samples: dict[str, list[float]] = {FORCE_TOPIC: [], VELOCITY_TOPIC: []}
    rate = 0.0
    with Reader(bag) as reader:
        for connection, _, data in reader.messages():
            message = store.deserialize_cdr(data, SAMPLE_BATCH)
            rate = message.sample_rate_hz
            for value in message.samples:
                samples[connection.topic].append(float(value))
    records = capture_impacts(
        np.array(samples[FORCE_TOPIC]), np.array(samples[VELOCITY_TOPIC]), rate, DEFAULT_CAPTURE
    )
    results = [
        analyze_impact(record, DEFAULT_CAPTURE, ANALYSIS, impact_id=k)
        for k, record in enumerate(records)
    ]
    summarize(results, ANALYSIS)
    return len(results)


def median_time(repeats: int, run, bag: Path) -> tuple[float, int]:
    times, value = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        value = run(bag)
        times.append(time.perf_counter() - start)
    return statistics.median(times), value


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeats', type=int, default=3)
    args = parser.parse_args()

    session = simulated_session(10)
    work = Path(tempfile.mkdtemp(prefix='bench_replay_'))
    try:
        bag = write_session_bag(work / 'session', session)
        size_mb = sum(f.stat().st_size for f in bag.iterdir()) / 1e6
        print(
            f'session: {len(session.hit_levels)} hits, {session.duration_s:.1f} s '
            f'({session.duration_s / 60:.1f} min) of two {session.sample_rate_hz / 1e3:g} kHz '
            f'channels, bag {size_mb:.0f} MB; median of {args.repeats} runs\n'
        )
        replay(bag)  # warm up: first calls compile and fault in what later runs reuse
        print(f'{"":44s} {"s":>7s} {"x real time":>12s}')
        rows = {}
        for name, run in (
            ('replay (fmm replay: read, capture, analyse)', replay),
            ('  of which: read batches only', read_only),
            ('  of which: read and capture only', read_and_capture),
            ('naive: samples via Python lists, then same', naive),
        ):
            seconds, value = median_time(args.repeats, run, bag)
            rows[name] = seconds
            print(f'{name:44s} {seconds:7.2f} {session.duration_s / seconds:12.0f}')
            if run in (replay, naive):
                assert value == len(session.hit_levels), (name, value)
        ours = rows['replay (fmm replay: read, capture, analyse)']
        speed = session.duration_s / ours
        ratio = rows['naive: samples via Python lists, then same'] / ours
        print(
            f'\nreplay: {speed:.0f}x real time (target >= {TARGET:.0f}x: '
            f'{"met" if speed >= TARGET else "NOT met"}); {ratio:.1f}x faster than the '
            'naive reader'
        )
    finally:
        shutil.rmtree(work)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
