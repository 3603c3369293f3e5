"""Bag write and read throughput for two 10 kHz channels in 500-sample batches.

Write: the core writer from numpy arrays, and from raw CDR bytes (what the recorder node
stores from a raw subscription), against rosbags' own writer (what the core writer wrapped
before it wrote MCAP through the mcap library) and a naive recorder that decodes each
message, copies its samples through a per-sample Python list and serializes it again.
Read: BagReader.batches() (aligned zero-copy views) and the recovery scan of an unclosed
bag, against a naive reader that appends every sample to a Python list.

Figures are medians of --repeats runs on one machine shared with other work, so expect
noise; the ratios compare runs made back to back in the same process.

    .venv/bin/python benchmarks/bench_bags.py [--seconds 120] [--repeats 5]
"""

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from results_file import QUICK_HELP, recorded
from rosbags.rosbag2 import Reader, StoragePlugin, Writer

from fmm_ros.constants import FORCE_TOPIC, VELOCITY_TOPIC, resolve_name
from fmm_ros.io.bags import SAMPLE_BATCH, BagReader, BagWriter, fmm_typestore, new_message

FS = 10_000.0
BATCH = 500


def session(seconds: float) -> tuple[np.ndarray, np.ndarray]:
    n = int(seconds * FS) // BATCH * BATCH
    rng = np.random.default_rng(0)
    return rng.normal(0, 50, n), rng.normal(0, 1e-3, n)


def raw_batches(force: np.ndarray, velocity: np.ndarray) -> list[tuple[str, int, bytes]]:
    """The serialized messages a raw subscription would hand the recorder, in order."""
    store = fmm_typestore()
    messages = []
    for start in range(0, len(force), BATCH):
        for topic, data, (quantity, unit) in (
            (FORCE_TOPIC, force, ('force', 'N')),
            (VELOCITY_TOPIC, velocity, ('velocity', 'm/s')),
        ):
            message = new_message(
                store,
                SAMPLE_BATCH,
                quantity=quantity,
                unit=unit,
                sample_rate_hz=FS,
                first_sample_index=start,
                samples=data[start : start + BATCH],
            )
            data = bytes(store.serialize_cdr(message, SAMPLE_BATCH))
            messages.append((resolve_name(topic), start, data))
    return messages


def write_numpy(path: Path, force, velocity, _raw) -> None:
    with BagWriter(path, time_origin_ns=0) as writer:
        writer.write_signals(force, velocity, FS)


def write_raw(path: Path, _force, _velocity, raw) -> None:
    with BagWriter(path, time_origin_ns=0) as writer:
        for topic, start, data in raw:
            writer.write_raw(topic, SAMPLE_BATCH, data, start * 100_000)


def write_rosbags(path: Path, _force, _velocity, raw) -> None:
    """The rosbags library's own rosbag2 writer, as the core writer used it (no chunk CRCs)."""
    store = fmm_typestore()
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {}
        for topic, start, data in raw:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, SAMPLE_BATCH, typestore=store)
            writer.write(connections[topic], start * 100_000, data)


def write_naive(path: Path, _force, _velocity, raw) -> None:
    """Decode, copy the samples sample by sample into a list, build and serialize anew."""
    store = fmm_typestore()
    with BagWriter(path, time_origin_ns=0) as writer:
        for topic, start, data in raw:
            message = store.deserialize_cdr(data, SAMPLE_BATCH)
            samples = [float(value) for value in message.samples]
            copy = new_message(
                store,
                SAMPLE_BATCH,
                header=message.header,
                quantity=message.quantity,
                unit=message.unit,
                sample_rate_hz=message.sample_rate_hz,
                first_sample_index=message.first_sample_index,
                samples=np.array(samples),
            )
            writer.write_message(topic, copy, start * 100_000)


def read_batches(path: Path) -> int:
    count = 0
    with BagReader(path) as reader:
        for batch in reader.batches():
            count += len(batch.force) + len(batch.velocity)
    return count


def read_recovering(path: Path) -> int:
    count = 0
    with BagReader(path, strict=False) as reader:
        assert reader.recovered
        for batch in reader.batches():
            count += len(batch.force) + len(batch.velocity)
    return count


def read_naive(path: Path) -> int:
    """rosbags, then every sample appended to a per-topic Python list."""
    store = fmm_typestore()
    samples: dict[str, list[float]] = {}
    with Reader(path) as reader:
        for connection, _, data in reader.messages():
            for value in store.deserialize_cdr(data, SAMPLE_BATCH).samples:
                samples.setdefault(connection.topic, []).append(float(value))
    return sum(len(np.array(values)) for values in samples.values())


def median_time(repeats: int, run) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        '--seconds', type=float, default=120.0, help='signal length per run [s] (default 120)'
    )
    parser.add_argument('--repeats', type=int, default=5)
    parser.add_argument('--quick', action='store_true', help=QUICK_HELP)
    args = parser.parse_args()
    if args.quick:
        args.seconds, args.repeats = 10.0, 1

    force, velocity = session(args.seconds)
    raw = raw_batches(force, velocity)
    samples = 2 * len(force)
    signal_s = len(force) / FS
    print(
        f'{signal_s:.0f} s of two {FS / 1e3:g} kHz channels = {samples:,} samples, '
        f'{len(raw)} messages of {BATCH} samples; median of {args.repeats} runs\n'
    )
    work = Path(tempfile.mkdtemp(prefix='bench_bags_'))
    try:
        print(f'{"write":34s} {"s":>8s} {"Msamples/s":>11s} {"MB/s":>7s} {"x real time":>12s}')
        write_times = {}
        for name, writer in (
            ('core writer, numpy batches', write_numpy),
            ('core writer, raw CDR (recorder)', write_raw),
            ("rosbags' writer, raw CDR", write_rosbags),
            ('naive: re-serialize via lists', write_naive),
        ):
            counter = iter(range(10**6))

            def run(writer=writer, counter=counter):
                writer(work / f'w{next(counter)}', force, velocity, raw)

            seconds = median_time(args.repeats, run)
            size = (work / 'w0' / 'w0.mcap').stat().st_size
            write_times[name] = seconds
            print(
                f'{name:34s} {seconds:8.3f} {samples / seconds / 1e6:11.2f} '
                f'{size / seconds / 1e6:7.1f} {signal_s / seconds:12.0f}'
            )
            for leftover in work.iterdir():
                shutil.rmtree(leftover)
        naive = write_times['naive: re-serialize via lists']
        for name in ('core writer, numpy batches', 'core writer, raw CDR (recorder)'):
            print(f'  {name}: {naive / write_times[name]:.1f}x the naive writer')
        rosbags = write_times["rosbags' writer, raw CDR"]
        print(
            f'  core writer, raw CDR (mcap library, chunk CRCs): '
            f"{rosbags / write_times['core writer, raw CDR (recorder)']:.2f}x rosbags' writer"
        )

        bag = work / 'bag'
        write_numpy(bag, force, velocity, raw)
        unclosed = work / 'unclosed'
        crashing = BagWriter(unclosed, time_origin_ns=0)  # flushed but never closed,
        crashing.open()  # as a killed recorder leaves it
        crashing.write_signals(force, velocity, FS)
        crashing.flush()
        size = (bag / 'bag.mcap').stat().st_size
        print(f'\n{"read":34s} {"s":>8s} {"Msamples/s":>11s} {"MB/s":>7s} {"x real time":>12s}')
        read_times = {}
        for name, reader, path in (
            ('BagReader.batches (views)', read_batches, bag),
            ('recovery scan of unclosed bag', read_recovering, unclosed),
            ('naive: samples into lists', read_naive, bag),
        ):
            assert reader(path) == samples
            seconds = median_time(args.repeats, lambda reader=reader, path=path: reader(path))
            read_times[name] = seconds
            print(
                f'{name:34s} {seconds:8.3f} {samples / seconds / 1e6:11.2f} '
                f'{size / seconds / 1e6:7.1f} {signal_s / seconds:12.0f}'
            )
        naive = read_times['naive: samples into lists']
        for name in ('BagReader.batches (views)', 'recovery scan of unclosed bag'):
            print(f'  {name}: {naive / read_times[name]:.1f}x the naive reader')
        crashing.close()
    finally:
        shutil.rmtree(work)
    return 0


if __name__ == '__main__':
    with recorded('bench_bags', quick='--quick' in sys.argv):
        raise SystemExit(main())
