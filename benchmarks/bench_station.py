"""The station's weight: its CPU at x1, the page's memory at x20, memory over a soak.

A recorded session (simulated, hits 8 s apart, 6 s records) is played by the player node into
the analyzer and the fitter, each its own process as `ros2 run` starts them, with the station
beside them and its page open in headless Chromium (Playwright).

1. x1: the station's CPU seconds (from /proc) per wall second while the player plays at
   recorded pace, the page open; beside it, in the same run, the analyzer's (the node the
   station must not outweigh) and the station's with no page open.
2. x20: the page's JavaScript heap (after a forced garbage collection) and the resident
   memory of the whole Chromium process tree, and whether the page kept up: every hit the
   analyzer reported is on the page, and how late (page clock minus the time the benchmark's
   own subscriber had it; same machine).
3. Soak: the session replayed at x20 over and over (each play a new acquisition) for
   `--soak-s`; the heap sampled after each play. Flat: the last quarter's mean within 20 % of
   the second quarter's (the page's bounded lists fill in the first).

A warm-up play at x20 comes first: discovery settles and numba compiles the model the station
draws over each decay (seconds of CPU once per process, not per hit).

Targets: station <= 5 % of a core at x1; page < 200 MB at x20; heap flat over the soak.
Run: .venv/bin/python benchmarks/bench_station.py [--quick] (full: writes RESULTS.md).
"""

from __future__ import annotations

import argparse
import os
import socket
import sys
import tempfile
import time
from pathlib import Path

import psutil
from playwright.sync_api import sync_playwright
from rclpy.node import Node

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from browser import CHROMIUM_ARGS, chromium_path  # noqa: E402
from results_file import write_section  # noqa: E402

from fmm_interfaces.msg import ImpactResult  # noqa: E402
from fmm_ros.constants import IMPACTS_TOPIC  # noqa: E402
from fmm_ros.ros.graph import InProcessGraph, private_domain_id  # noqa: E402
from fmm_ros.ros.launch import start_processes, stop_processes, with_wiring  # noqa: E402
from fmm_ros.ros.qos import RESULT_QOS  # noqa: E402
from fmm_ros.sim.session import simulated_session, write_session_bag  # noqa: E402

CLOCK_TICKS = os.sysconf('SC_CLK_TCK')
CPU_TARGET = 0.05
MEMORY_TARGET_MB = 200.0
FLAT_TOLERANCE = 0.2
NODES = ('analyzer', 'fitter', 'station')


class Arrivals(Node):
    """When each ImpactResult reached the benchmark (wall clock), in arrival order.

    Impact ids are stable (the trigger's time in the acquisition), so a bag played again
    reports the same ids: arrivals are counted, and `at` holds each id's latest arrival.
    """

    def __init__(self, **kwargs):
        super().__init__('bench_arrivals', **kwargs)
        self.at: dict[int, float] = {}
        self.order: list[int] = []
        self.create_subscription(ImpactResult, IMPACTS_TOPIC, self._arrived, RESULT_QOS)

    def _arrived(self, msg: ImpactResult) -> None:
        self.at[msg.impact_id] = time.time()
        self.order.append(msg.impact_id)


def cpu_s(pid: int) -> float:
    """User + system CPU seconds of a process so far."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


class Bench:
    """The player, analyzer, fitter and station as processes, and the page in Chromium."""

    def __init__(self, bag: Path, port: int) -> None:
        self.bag = bag
        self.port = port
        self.processes: dict[str, object] = {}

    def overrides(self, rate_factor: float) -> dict:
        """Each node's parameters, the player at rate_factor."""
        from rclpy.parameter import Parameter

        values = {
            'player': {'bag_path': str(self.bag), 'rate_factor': rate_factor},
            'analyzer': {'window_s': 6.0},
            'station': {'port': self.port, 'target_hits_per_level': 1000},
        }
        return with_wiring(
            ('player', *NODES),
            {n: [Parameter(k, value=v) for k, v in p.items()] for n, p in values.items()},
        )

    def start(self, names: tuple[str, ...], rate_factor: float) -> None:
        """Start these nodes as processes."""
        for name, process in zip(
            names, start_processes(names, None, self.overrides(rate_factor)), strict=True
        ):
            self.processes[name] = process

    def play(self, rate_factor: float, arrivals: Arrivals, hits: int) -> None:
        """Play the bag once (a new player process) until the analyzer reported its hits.

        The player stays up once the bag is played (as `ros2 bag play` without --loop would
        not): it is stopped here.
        """
        expected = len(arrivals.order) + hits
        self.start(('player',), rate_factor)
        deadline = time.monotonic() + 3600
        while len(arrivals.order) < expected and time.monotonic() < deadline:
            time.sleep(0.05)
        stop_processes([self.processes.pop('player')], nodes=['player'])
        if len(arrivals.order) < expected:
            raise RuntimeError(f'{expected - len(arrivals.order)} hits never reported')

    def stop(self) -> None:
        """Stop every node still running."""
        names = list(self.processes)
        stop_processes([self.processes.pop(n) for n in names], nodes=names)


def wait_listening(port: int, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        with socket.socket() as probe:
            if probe.connect_ex(('127.0.0.1', port)) == 0:
                return
        time.sleep(0.1)
    raise RuntimeError('the station never listened')


def page_memory(cdp) -> tuple[float, float, float]:
    """(JS heap after garbage collection, the page renderer's unique and resident memory) [MB].

    The page is the one renderer process (one tab); the browser and GPU processes are
    Chromium's, there with any page. Unique memory (USS) is what closing the page frees;
    resident memory (RSS) also counts the libraries it shares with Chromium's other processes.
    """
    cdp.send('HeapProfiler.collectGarbage')
    metrics = {m['name']: m['value'] for m in cdp.send('Performance.getMetrics')['metrics']}
    renderers = [
        p
        for p in psutil.Process().children(recursive=True)
        if 'chrom' in p.name().lower() and '--type=renderer' in ' '.join(p.cmdline())
    ]
    memory = max((p.memory_full_info() for p in renderers), key=lambda m: m.uss)
    return metrics['JSHeapUsedSize'] / 1e6, memory.uss / 1e6, memory.rss / 1e6


def run(quick: bool, soak_s: float) -> str:
    levels = ('low',) if quick else ('low', 'medium', 'high')
    session = simulated_session(2 if quick else 4, spacing_s=8.0, levels=levels, seed=5)
    hits = len(session.hit_start_indices)
    tmp = Path(tempfile.mkdtemp(prefix='bench_station_'))
    # Stamped with today's clock, as a recorder stamps a live session.
    bag = write_session_bag(tmp / 'session', session, time_origin_ns=time.time_ns())
    domain = private_domain_id()
    os.environ['ROS_DOMAIN_ID'] = str(domain)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    bench = Bench(bag, free_port())
    rows = []
    with InProcessGraph(domain_id=domain) as graph, sync_playwright() as playwright:
        arrivals = graph.add(Arrivals)
        graph.start()
        bench.start(NODES, 1.0)
        wait_listening(bench.port)
        station, analyzer = bench.processes['station'].pid, bench.processes['analyzer'].pid
        # Warm up: discovery settles, numba compiles the model the station draws over a decay.
        bench.play(20.0, arrivals, hits)
        # 1. x1, first without a page, then with one.
        idle = (cpu_s(station), time.monotonic())
        time.sleep(3.0 if quick else 15.0)
        idle_share = (cpu_s(station) - idle[0]) / (time.monotonic() - idle[1])
        browser = playwright.chromium.launch(
            executable_path=chromium_path(), headless=True, args=list(CHROMIUM_ARGS)
        )
        page = browser.new_page(viewport={'width': 1500, 'height': 1300})
        cdp = page.context.new_cdp_session(page)
        cdp.send('Performance.enable')
        page.goto(f'http://127.0.0.1:{bench.port}/', wait_until='load')
        start = (cpu_s(station), cpu_s(analyzer), time.monotonic())
        bench.play(1.0, arrivals, hits)
        wall = time.monotonic() - start[2]
        station_share = (cpu_s(station) - start[0]) / wall
        analyzer_share = (cpu_s(analyzer) - start[1]) / wall
        rows.append(
            f'| x1, {session.duration_s:.0f} s of signal, page open | station '
            f'{station_share:.1%} of a core (target <= {CPU_TARGET:.0%}) | analyzer '
            f'{analyzer_share:.1%}; station idle (no page, nothing playing) {idle_share:.1%} |'
        )
        # 2. x20: memory, and did the page keep up?
        before = len(arrivals.order)
        bench.play(20.0, arrivals, hits)
        time.sleep(3.0)
        heap, uss, rss = page_memory(cdp)
        seen = page.evaluate('window.stationPage.hitSeen')
        new = arrivals.order[before:]
        missing = [i for i in new if str(i) not in seen]
        late = max((seen[str(i)] / 1e3 - arrivals.at[i] for i in new if str(i) in seen), default=0)
        rows.append(
            f'| x20, {len(new)} hits | page: JS heap {heap:.1f} MB, renderer {uss:.0f} MB '
            f'unique (target < {MEMORY_TARGET_MB:.0f} MB), {rss:.0f} MB resident | '
            f'{len(new) - len(missing)} of {len(new)} hits on the page, the latest '
            f'{late:.2f} s after its ImpactResult |'
        )
        # 3. Soak at x20.
        heaps = [heap]
        soak_start = time.monotonic()
        plays = 0
        while time.monotonic() - soak_start < soak_s:
            bench.play(20.0, arrivals, hits)
            plays += 1
            heaps.append(page_memory(cdp)[0])
        _, uss_end, rss_end = page_memory(cdp)
        # The page's bounded lists (12 hits' figures, 500 rows) fill in the first quarter:
        # flat means the last quarter's heap is where the second quarter's was.
        quarter = max(1, len(heaps) // 4)
        head, tail = heaps[quarter : 2 * quarter] or heaps[:1], heaps[-quarter:]
        drift = (sum(tail) / len(tail)) / (sum(head) / len(head)) - 1.0
        rows.append(
            f'| soak: {plays} plays at x20 in {time.monotonic() - soak_start:.0f} s | heap '
            f'{" → ".join(f"{h:.1f}" for h in heaps[:: max(1, len(heaps) // 6)])} MB, '
            f'{drift:+.0%} second to last quarter (flat: within ±{FLAT_TOLERANCE:.0%}) | '
            f'renderer {uss_end:.0f} MB unique, {rss_end:.0f} MB resident at the end |'
        )
        browser.close()
        bench.stop()
    verdicts = [
        f'station CPU at x1 {"meets" if station_share <= CPU_TARGET else "MISSES"} the 5 % target',
        f'page memory at x20 {"meets" if max(heap, uss) < MEMORY_TARGET_MB else "MISSES"} the '
        f'200 MB target ({"kept up" if not missing else f"{len(missing)} hits missing"})',
        f'heap over the soak {"flat" if abs(drift) <= FLAT_TOLERANCE else "NOT flat"}',
    ]
    return (
        '| run | measured | beside it |\n|---|---|---|\n'
        + '\n'.join(rows)
        + '\n\n'
        + '; '.join(verdicts)
        + '.\n'
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='short runs, writes nothing')
    parser.add_argument('--soak-s', type=float, default=None, help='soak length [s]')
    args = parser.parse_args()
    soak_s = args.soak_s if args.soak_s is not None else (5.0 if args.quick else 300.0)
    text = run(args.quick, soak_s)
    print(text)
    write_section('station', text, quick=args.quick)


if __name__ == '__main__':
    main()
