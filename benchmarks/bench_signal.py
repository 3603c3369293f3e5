"""Signal-core speed: one 33 s impact analysed, and streaming capture's share of a core.

Targets: one impact (2 x 330,000 samples) analysed in <= 50 ms; streaming both
10 kHz channels in 500-sample batches below 2 % of one core. Each is measured against a naive
baseline in the same run. Medians of several repeats, since the 2 cores are shared.

    .venv/bin/python benchmarks/bench_signal.py [--repeats N]
"""

import argparse
import statistics
import sys
import time

import numpy as np
import scipy.signal
from results_file import QUICK_HELP, recorded

from fmm_ros.core.signal.analysis import analyze_impact
from fmm_ros.core.signal.capture import CaptureConfig, ImpactCapture, find_triggers
from fmm_ros.core.signal.records import ImpactRecord

RATE_HZ = 10_000.0
BATCH = 500
MASS_KG, DAMPING_N_S_PER_M, STIFFNESS_N_PER_M = 10.391, 25.0, 1982.0


def stream(seconds: float, hits_s: list[float], seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Force and velocity of a damped FMM-like oscillator hit by 1000 N, 4 ms half-sines."""
    n = int(seconds * RATE_HZ)
    force = np.zeros(n)
    pulse = 1000.0 * np.sin(np.pi * np.arange(41) / 40)
    for at in hits_s:
        start = int(at * RATE_HZ)
        force[start : start + pulse.size] += pulse
    num, den, _ = scipy.signal.cont2discrete(
        ([1.0, 0.0], [MASS_KG, DAMPING_N_S_PER_M, STIFFNESS_N_PER_M]), 1 / RATE_HZ, method='foh'
    )
    velocity = scipy.signal.lfilter(num.ravel(), den, force)
    rng = np.random.default_rng(seed)
    return force + rng.normal(0, 0.2, n), velocity + rng.normal(0, 1e-6, n)


def naive_analysis(force: list, velocity: list) -> tuple[float, float]:
    """The straightforward port: fresh arrays, full complex FFTs, FRF over every bin."""
    f, v = np.array(force), np.array(velocity)
    spectrum_f, spectrum_v = np.fft.fft(f), np.fft.fft(v)
    frequency = np.fft.fftfreq(f.size, 1 / RATE_HZ)
    mobility = spectrum_v / spectrum_f
    with np.errstate(divide='ignore', invalid='ignore'):
        receptance = mobility / (2j * np.pi * frequency)
    band = (frequency >= 1) & (frequency <= 100)
    peak = int(np.argmax(np.where(band, np.abs(receptance), 0.0)))
    return float(np.trapezoid(f, dx=1 / RATE_HZ)), float(np.abs(receptance[peak]))


def median_ms(function, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return 1e3 * statistics.median(times)


def bench_analysis(repeats: int) -> None:
    force, velocity = stream(34.0, [1.0])
    start = int(1.0 * RATE_HZ) - 100
    record = ImpactRecord(
        force[start : start + 330_000],
        velocity[start : start + 330_000],
        RATE_HZ,
        record_start_sample_index=start,
        trigger_sample_index=start + 100,
    )
    analyze_impact(record)  # warm-up: FFT plans, imports
    ours = median_ms(lambda: analyze_impact(record), repeats)
    as_lists = (record.force_n.tolist(), record.velocity_m_s.tolist())
    naive = median_ms(lambda: naive_analysis(*as_lists), repeats)
    print(
        f'one 33 s impact (2 x {record.force_n.size:,} samples) analysed: {ours:6.1f} ms '
        f'(target <= 50 ms; flags, impulse, contact, rfft FRFs, peak)'
    )
    print(
        f'  naive (fresh arrays, full np.fft.fft, FRF on all bins):     {naive:6.1f} ms '
        f'-> {naive / ours:4.1f}x slower'
    )


def feed_batches(
    capture: ImpactCapture, force: np.ndarray, velocity: np.ndarray, analyse: bool
) -> int:
    """Feed both channels in 500-sample batches as the analyzer node does; count impacts."""
    impacts = 0
    for first in range(0, force.size, BATCH):
        done = capture.feed('force', first, force[first : first + BATCH], RATE_HZ)
        done += capture.feed('velocity', first, velocity[first : first + BATCH], RATE_HZ)
        for record in done:
            if analyse:
                analyze_impact(record)
            capture.recycle(record)
            impacts += 1
    return impacts


def naive_stream(force: np.ndarray, velocity: np.ndarray, config: CaptureConfig) -> int:
    """Python lists grown per batch, triggers searched per batch, records as fresh arrays."""
    kept_f, kept_v, pending, impacts = [], [], [], 0
    window, pre = int(config.window_s * RATE_HZ), int(config.pretrigger_s * RATE_HZ)
    last = -(10**9)
    for first in range(0, force.size, BATCH):
        batch_f = force[first : first + BATCH]
        kept_f.extend(batch_f.tolist())
        kept_v.extend(velocity[first : first + BATCH].tolist())
        for offset in np.flatnonzero(batch_f >= config.trigger_level_n):
            index = first + int(offset)
            if index - last >= config.min_spacing_s * RATE_HZ:
                pending.append(index - pre)
                last = index
        for start in [s for s in pending if s + window <= len(kept_f)]:
            np.array(kept_f[start : start + window]), np.array(kept_v[start : start + window])
            pending.remove(start)
            impacts += 1
    return impacts


def cpu_seconds(function) -> float:
    start = time.process_time()
    function()
    return time.process_time() - start


def bench_streaming(repeats: int) -> None:
    seconds = 120.0
    force, velocity = stream(seconds, [2.0, 40.0, 78.0])
    config = CaptureConfig()
    expected = len(find_triggers(force, RATE_HZ, config))
    results = {}
    for label, analyse in (('capture only', False), ('capture + analysis', True)):
        runs = []
        for _ in range(repeats):
            capture = ImpactCapture(config)
            runs.append(
                cpu_seconds(lambda c=capture, a=analyse: feed_batches(c, force, velocity, a))
            )
        results[label] = statistics.median(runs)
    naive = statistics.median(
        cpu_seconds(lambda: naive_stream(force, velocity, config)) for _ in range(repeats)
    )
    capture = ImpactCapture(config)
    assert feed_batches(capture, force, velocity, False) == expected == 3
    batches = 2 * force.size // BATCH
    ours = results['capture only']
    print(
        f'streaming 2 x 10 kHz in {BATCH}-sample batches, {seconds:.0f} s with {expected} '
        f'impacts ({batches:,} batches):'
    )
    print(
        f'  capture only:        {100 * ours / seconds:6.3f} % of one core '
        f'({1e6 * ours / batches:5.1f} us per batch; target < 2 %)'
    )
    both = results['capture + analysis']
    print(f'  capture + analysis:  {100 * both / seconds:6.3f} % of one core')
    print(
        f'  naive (lists per batch, fresh record arrays): {100 * naive / seconds:6.3f} % '
        f'-> {naive / ours:4.1f}x the CPU, and its memory grows without bound'
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeats', type=int, default=7)
    parser.add_argument('--quick', action='store_true', help=QUICK_HELP)
    args = parser.parse_args()
    if args.quick:
        args.repeats = 1
    bench_analysis(args.repeats)
    bench_streaming(max(3, args.repeats // 2))


if __name__ == '__main__':
    with recorded('bench_signal', quick='--quick' in sys.argv):
        main()
