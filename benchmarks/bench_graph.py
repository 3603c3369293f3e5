"""The live rig's speed: whole graph in one process, and the analyzer's CPU share.

1. hammer_sim, rig_sim, analyzer, fitter and recorder on one executor, the hammer asked for
   x1000 so the graph runs as fast as it can: real-time factor = seconds of signal (two
   10 kHz channels) per wall second. Batches sized as `fmm demo` sizes them, against the
   naive fixed 500-sample batch at the same speed request.
2. The analyzer alone in its own process, fed two 10 kHz channels at real-time pace by a
   source in another process: its CPU seconds (from /proc) per second of signal, at the
   default 500-sample batches and at 50-sample batches (what per-message cost does).

Run: .venv/bin/python benchmarks/bench_graph.py [--quick]
"""

import argparse
import os
import sys
import time

from rclpy.parameter import Parameter
from results_file import QUICK_HELP, recorded

from fmm_ros.ros.demo import SessionConfig
from fmm_ros.ros.graph import InProcessGraph, private_domain_id
from fmm_ros.ros.launch import node_command, start_processes, stop_processes
from fmm_ros.ros.nodes.analyzer import Analyzer
from fmm_ros.ros.nodes.fitter import Fitter
from fmm_ros.ros.nodes.hammer_sim import HammerSim
from fmm_ros.ros.nodes.recorder import Recorder
from fmm_ros.ros.nodes.rig_sim import RigSim

CLOCK_TICKS = os.sysconf('SC_CLK_TCK')


def whole_graph(batch_size: int, tmp: str, hits_per_level: int = 2) -> tuple[float, int]:
    """Real-time factor of the five-node graph asked to run at x1000, and impacts accepted.

    The clock stops when the analyzer has reported the last impact, whose record ends
    33 s after the last hit: queues may hold many batches, so the source finishing early
    says nothing about the graph.
    """

    def p(**values):
        return [Parameter(k, value=v) for k, v in values.items()]

    with InProcessGraph() as graph:
        hammer = graph.add(
            HammerSim,
            parameter_overrides=p(
                rate_factor=1000.0,
                batch_size=batch_size,
                max_batches_per_s=0.0,  # the batch size compared, not the one the pace picks
                hits_per_level=hits_per_level,
            ),
        )
        graph.add(RigSim)
        analyzer = graph.add(Analyzer)
        graph.add(Fitter)
        graph.add(Recorder, parameter_overrides=p(bag_path=f'{tmp}/bag_{batch_size}'))
        for node in (hammer, analyzer):
            node.get_logger().set_level(40)
        total = len(hammer.schedule)
        graph.start()
        start = time.monotonic()
        while analyzer.impacts_reported < total:
            time.sleep(0.005)
        wall = time.monotonic() - start
        last = analyzer.results[-1]
        signal_s = last.record_start_sample_index / last.sample_rate_hz + last.record_duration_s
        return signal_s / wall, analyzer.impacts_accepted


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process so far [s]."""
    fields = open(f'/proc/{pid}/stat').read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def analyzer_share(batch_size: int, seconds: float = 20.0) -> float:
    """Analyzer CPU seconds per signal second, fed at real time from another process."""
    os.environ['ROS_DOMAIN_ID'] = str(private_domain_id())
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    overrides = {
        'hammer_sim': [
            Parameter('batch_size', value=batch_size),
            Parameter('first_hit_s', value=1.0),
            Parameter('hit_spacing_s', value=8.0),
            Parameter('wait_for_consumers', value=['rig_sim', 'analyzer']),
        ],
        'rig_sim': [Parameter('wait_for_consumers', value=['analyzer'])],
        'analyzer': [],
    }
    processes = start_processes(['analyzer'], None, overrides)
    time.sleep(3.0)  # analyzer up and idle before the source starts
    sources = start_processes(['hammer_sim', 'rig_sim'], None, overrides)
    try:
        time.sleep(3.0)  # discovery, then measure over steady streaming with hits in it
        cpu0, wall0 = cpu_seconds(processes[0].pid), time.monotonic()
        time.sleep(seconds)
        cpu1, wall1 = cpu_seconds(processes[0].pid), time.monotonic()
    finally:
        stop_processes(sources + processes)
    return (cpu1 - cpu0) / (wall1 - wall0)


def main() -> None:
    import tempfile

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help=QUICK_HELP)
    quick = parser.parse_args().quick
    levels = 1 if quick else 2
    hits = 3 * levels
    demo_batch = SessionConfig(out_dir='.', rate_factor=1000.0).batch()
    print(
        f'Whole simulated graph in one process ({hits} hits 40 s apart, two 10 kHz channels, '
        '5 nodes, recording); clock stopped at the last impact reported'
    )
    with tempfile.TemporaryDirectory() as tmp:
        naive, naive_ok = whole_graph(500, tmp, levels)
        sized, sized_ok = whole_graph(demo_batch, tmp, levels)
    print(
        f'  naive 500-sample batches          x{naive:7.1f} real time  ({naive_ok}/{hits} accepted)'
    )
    print(
        f'  {demo_batch}-sample batches (fmm demo) x{sized:7.1f} real time  ({sized_ok}/{hits} '
        f'accepted; {sized / naive:.1f}x the naive)   target >= x20: '
        f'{"met" if sized >= 20 else "MISSED"}'
    )
    print(
        f'\nAnalyzer alone at real-time pace ({node_command("analyzer")[0]}), CPU of its '
        'process per second of signal'
    )
    seconds = 3.0 if quick else 20.0
    default = analyzer_share(500, seconds)
    small = analyzer_share(50, seconds)
    print(
        f'  500-sample batches (default)      {default * 100:6.2f} % of one core   '
        f'target < 5 %: {"met" if default < 0.05 else "MISSED"}'
    )
    print(
        f'  50-sample batches (naive)         {small * 100:6.2f} % of one core   '
        f'({small / default:.1f}x the default)'
    )


if __name__ == '__main__':
    with recorded('bench_graph', quick='--quick' in sys.argv):
        main()
