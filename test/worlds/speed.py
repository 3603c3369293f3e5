"""Speed of the generator, printed as figures and as a ratio of the two plant paths.

Run from test/: `../.venv/bin/python -m worlds.speed`. Times are process CPU times (robust on
a shared machine), medians of repeated runs, of 33 s records at the paper's medium level.
"""

import statistics
import time
from collections.abc import Callable

import numpy as np

from worlds.friction import Coulomb, Stribeck
from worlds.lab import impact_record, record_session
from worlds.motion import PlantState, simulate_motion
from worlds.pulses import HalfSine, PlacedPulse
from worlds.world import CubicStiffness, World

_REPEATS = 15


def _median_s(run: Callable[[], object], repeats: int = _REPEATS) -> float:
    run()
    times = []
    for _ in range(repeats):
        start = time.process_time()
        run()
        times.append(time.process_time() - start)
    return statistics.median(times)


def main() -> None:
    """Print the per-record and per-session costs."""
    world = World()
    hit = [PlacedPulse(HalfSine.for_impulse(1000.0, 1.42), 0.05)]
    rng = np.random.default_rng(0)
    rows = {}
    for method in ('auto', 'general'):
        rows[f'plant only, {method}'] = _median_s(
            lambda m=method: simulate_motion(world, hit, 0.0, 33.0, PlantState(2e-4), method=m)
        )
        rows[f'33 s record, {method}'] = _median_s(
            lambda m=method: impact_record(world, rng, pulse=hit[0].pulse, method=m)
        )
    stribeck = World(friction=Stribeck(Coulomb(0.1), 0.03, 3e-3), effects=(CubicStiffness(2e6),))
    rows['plant only, Stribeck + cubic'] = _median_s(
        lambda: simulate_motion(stribeck, hit, 0.0, 33.0, PlantState(2e-4))
    )
    rows['20-hit session (~12 min), auto'] = _median_s(
        lambda: record_session(world, rng, hits=20), repeats=3
    )
    for name, seconds in rows.items():
        print(f'{name:36s} {seconds * 1e3:9.1f} ms')
    plant = rows['plant only, general'] / rows['plant only, auto']
    record = rows['33 s record, general'] / rows['33 s record, auto']
    print(f'general / auto: plant only {plant:.1f}x, whole record {record:.1f}x')


if __name__ == '__main__':
    main()
