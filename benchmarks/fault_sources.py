"""Sources we did not write, into the analyzer as `ros2 run` starts it: what is lost.

Each case starts the analyzer as its own process (the package's params file, 6 s records)
and `benchmarks/foreign_source.py` as another: a plain rclpy publisher of a simulated
session (hits 8 s apart) at x1, x10, x50 or x100 real time in batches of 100, 500 or 5,000
samples, with no flow control. Per case it counts, from outside the analyzer:

- samples sent per channel against those the analyzer's final ledger received, and what
  that ledger calls missing (it must never say fewer than were lost);
- hits sent against hits reported on fmm/impacts (distinct trigger indices);
- what the analyzer named on /diagnostics above OK (a loss must be named there).

A case passes when nothing was lost and every hit was reported, or when what was lost was
named on /diagnostics. Over repeated runs it prints the rate of each outcome.

    .venv/bin/python benchmarks/fault_sources.py [--quick] [--runs N]
        [--rates 1 10 50 100] [--batches 100 500 5000] [--history keep_last|keep_all]

--quick: x50 and x100 in 500-sample batches, one run each. A run given --runs writes its
printout into RESULTS.md (section fault_sources); others write nothing. x1 runs the 24 s
session in real time, so the full grid takes a while.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from results_file import recorded  # noqa: E402
from stress_rig import fresh_domain, ledgers  # noqa: E402

from fmm_interfaces.msg import ImpactResult  # noqa: E402
from fmm_ros.constants import DIAGNOSTICS_TOPIC, IMPACTS_TOPIC  # noqa: E402
from fmm_ros.ros.graph import InProcessGraph  # noqa: E402
from fmm_ros.ros.launch import (  # noqa: E402
    default_params_file,
    parse_overrides,
    start_processes,
    stop_processes,
)
from fmm_ros.ros.qos import DIAGNOSTICS_QOS, RESULT_QOS  # noqa: E402
from fmm_ros.sim.session import simulated_session  # noqa: E402

HERE = Path(__file__).resolve().parent
HITS_PER_LEVEL = 1  # 3 hits, 8 s apart: a 24 s session
SPACING_S = 8.0
SEED = 3


class Watch:
    """What the analyzer publishes: impacts, and its /diagnostics above OK."""

    def __init__(self, node) -> None:
        self.triggers: set[int] = set()
        self.named: dict[str, str] = {}  # each status's last message above OK
        self.ever_named: set[str] = set()  # every such message seen
        self.received: dict[str, int] = {}
        self.changed_at = time.monotonic()
        node.create_subscription(ImpactResult, IMPACTS_TOPIC, self._impact, RESULT_QOS)
        node.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, self._diag, DIAGNOSTICS_QOS)

    def _impact(self, msg: ImpactResult) -> None:
        self.triggers.add(int(msg.trigger_sample_index))
        self.changed_at = time.monotonic()

    def _diag(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if 'analyzer' not in status.name:
                continue
            if status.level != DiagnosticStatus.OK:
                self.named[status.name] = status.message
                self.ever_named.add(f'{status.name}: {status.message}')
            for kv in status.values:
                if kv.key.endswith(' received samples'):
                    if self.received.get(kv.key) != int(kv.value):
                        self.changed_at = time.monotonic()
                    self.received[kv.key] = int(kv.value)


@dataclass
class Outcome:
    """One case's figures, from outside the analyzer."""

    rate: float
    batch: int
    sent: int
    received: dict[str, int] = field(default_factory=dict)
    said_missing: dict[str, int] = field(default_factory=dict)
    hits_sent: int = 0
    hits_reported: int = 0
    named: list[str] = field(default_factory=list)
    source_line: str = ''
    ever_named: list[str] = field(default_factory=list)
    log: str = ''

    @property
    def lost(self) -> int:
        """Samples sent that the analyzer never received, both channels."""
        return sum(self.sent - got for got in self.received.values()) if self.received else -1

    @property
    def undercounted(self) -> bool:
        """The ledger says fewer missing than were lost on some channel."""
        return any(
            self.said_missing.get(q, 0) < self.sent - got for q, got in self.received.items()
        )

    @property
    def clean(self) -> bool:
        """Nothing lost, every hit reported."""
        return self.lost == 0 and self.hits_reported == self.hits_sent

    @property
    def verdict(self) -> str:
        """'clean', 'named' (a loss the ledger counts in full and /diagnostics names), 'LOST'."""
        if self.clean:
            return 'clean'
        if self.named and not self.undercounted:
            return 'named'
        return 'LOST'


def run_case(
    work: Path,
    rate: float,
    batch: int,
    history: str,
    settle_s: float = 4.0,
    extra: tuple[str, ...] = (),
) -> Outcome:
    """One foreign source into one analyzer process; the figures of it.

    extra: more arguments for foreign_source.py (`--damage`).
    """
    fresh_domain()
    work.mkdir(parents=True)
    session = simulated_session(HITS_PER_LEVEL, spacing_s=SPACING_S, seed=SEED)
    outcome = Outcome(rate, batch, session.force_n.size, hits_sent=len(session.hit_levels))
    overrides = parse_overrides(['analyzer.window_s=6.0'], ['analyzer'])
    processes = start_processes(['analyzer'], default_params_file(), overrides, log_dir=work)
    try:
        with InProcessGraph(domain_id=int(os.environ['ROS_DOMAIN_ID'])) as graph:
            watch = Watch(graph.add(_node_factory('foreign_source_watch')))
            graph.start()
            source = subprocess.run(
                [
                    sys.executable,
                    str(HERE / 'foreign_source.py'),
                    f'--rate-factor={rate}',
                    f'--batch={batch}',
                    f'--hits-per-level={HITS_PER_LEVEL}',
                    f'--spacing-s={SPACING_S}',
                    f'--seed={SEED}',
                    f'--history={history}',
                    *extra,
                ],
                capture_output=True,
                text=True,
                timeout=600,
            )
            outcome.source_line = source.stdout.strip() or source.stderr.strip()[-300:]
            # The analyzer may still be working through its queue: wait until it is quiet.
            deadline = time.monotonic() + 300
            while time.monotonic() < deadline and time.monotonic() - watch.changed_at < settle_s:
                time.sleep(0.2)
            outcome.hits_reported = len(watch.triggers)
            outcome.named = sorted(f'{k}: {v}' for k, v in watch.named.items())
            outcome.ever_named = sorted(watch.ever_named)
    finally:
        stop_processes(processes, nodes=['analyzer'])
    outcome.log = (work / 'analyzer.log').read_text(errors='replace')
    for entry in ledgers(work):
        if entry.node == 'analyzer':
            outcome.received[entry.channel] = entry.received
            outcome.said_missing[entry.channel] = entry.missing
    return outcome


def two_sources_case(work: Path, rate: float = 10.0) -> tuple[list[str], str]:
    """Two foreign sources (other node names and frame_ids) on the same topics at once.

    Returns every message the analyzer published on /diagnostics above OK, and its log.
    """
    fresh_domain()
    work.mkdir(parents=True)
    overrides = parse_overrides(['analyzer.window_s=6.0'], ['analyzer'])
    processes = start_processes(['analyzer'], default_params_file(), overrides, log_dir=work)
    try:
        with InProcessGraph(domain_id=int(os.environ['ROS_DOMAIN_ID'])) as graph:
            watch = Watch(graph.add(_node_factory('two_sources_watch')))
            graph.start()
            sources = [
                subprocess.Popen(
                    [
                        sys.executable,
                        str(HERE / 'foreign_source.py'),
                        f'--rate-factor={rate}',
                        f'--node-name={name}',
                        f'--frame-id={name}',
                        '--linger-s=1',
                    ],
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                )
                for name in ('daq_one', 'daq_two')
            ]
            for source in sources:
                source.wait(timeout=300)
            time.sleep(1.5)
            named = sorted(watch.ever_named)
    finally:
        stop_processes(processes, nodes=['analyzer'])
    return named, (work / 'analyzer.log').read_text(errors='replace')


def _node_factory(name: str):
    from rclpy.node import Node

    return lambda **kwargs: Node(name, **kwargs)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true')
    parser.add_argument('--runs', type=int, default=1)
    parser.add_argument('--rates', type=float, nargs='+', default=[1, 10, 50, 100])
    parser.add_argument('--batches', type=int, nargs='+', default=[100, 500, 5000])
    parser.add_argument('--history', choices=('keep_all', 'keep_last'), default='keep_last')
    args = parser.parse_args(argv)
    rates, batches = (args.rates, args.batches) if not args.quick else ([50, 100], [500])
    root = Path(tempfile.mkdtemp(prefix='fmm_fault_sources_'))
    bad = 0
    try:
        print(f'load: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f}; history {args.history}')
        for rate in rates:
            for batch in batches:
                verdicts = []
                for run in range(args.runs):
                    outcome = run_case(root / f'x{rate:g}_{batch}_{run}', rate, batch, args.history)
                    verdicts.append(outcome.verdict)
                    bad += outcome.verdict == 'LOST'
                    print(
                        f'x{rate:g} batch {batch} run {run}: {outcome.verdict}; '
                        f'lost {outcome.lost} of {2 * outcome.sent} samples, ledger says '
                        f'{sum(outcome.said_missing.values())} missing; hits '
                        f'{outcome.hits_reported} of {outcome.hits_sent}; source: '
                        f'{outcome.source_line}'
                        + (f'; named: {" | ".join(outcome.named)}' if outcome.named else ''),
                        flush=True,
                    )
                counts = {v: verdicts.count(v) for v in ('clean', 'named', 'LOST')}
                print(
                    f'== x{rate:g} batch {batch}: '
                    + ', '.join(f'{v} {n} of {len(verdicts)}' for v, n in counts.items()),
                    flush=True,
                )
        print(f'load after: {os.getloadavg()[0]:.2f}')
    finally:
        if not os.environ.get('FMM_KEEP'):
            shutil.rmtree(root, ignore_errors=True)
        else:
            print(root)
    return 1 if bad else 0


if __name__ == '__main__':
    with recorded('fault_sources', quick='--quick' in sys.argv or '--runs' not in sys.argv):
        raise SystemExit(main())
