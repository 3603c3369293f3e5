"""The respawn family: each node of the rig killed (SIGKILL) and started again, over many runs.

The simulated rig as `launch_scripts/sim_rig.py --processes --station` starts it (one process
per node, the package's params file), a short session (hits 8 s apart, 6 s records, at a few
times real time), set up as a rig that respawns its nodes: the fitter keeps its held impacts
in a `state_dir`, and hammer_sim and rig_sim wait up to `silent_after_s` (120 s) for an
awaited consumer that fell silent. Once the analyzer has reported its first hit, one node
(analyzer, fitter, recorder, station, hammer_sim or rig_sim) is killed with SIGKILL and
started again at once, as a process manager respawns it. When the session is over and the
graph quiet, from outside the nodes:

- **accepted live**: the ImpactResults the analyzer(s) published accepted, read from the
  bags (every bag the recorders wrote: a respawned recorder writes `<bag>_1` beside the
  first, which it never touches);
- **held**: the fitter's fmm/fit_friction over every impact it holds (the response names
  the impacts it fitted);
- **counted**: the newest FrictionEstimate (the live mu) on fmm/friction, its impact_ids;
- **replayed**: `replay_bag` of the newest bag alone (as `fmm replay` runs it), its
  accepted impact ids;
- hits sent by the hammer against hits reported, and whether a hit the kill cost was named
  (a log line: the analyzer's join, the fitter's samples it did not get).

A run passes each check when every accepted-live impact id is in that set. Per node it
prints the rate of runs held / counted / replayed over the runs, with the load average.

    .venv/bin/python benchmarks/fault_respawn.py [--quick] [--runs N] [--nodes NAME ...]
        [--rate X]

--quick: one run of the fitter's respawn (CI, through test/test_fault_respawn.py); writes
nothing. A run given --runs writes its printout into RESULTS.md (section fault_respawn, or
fault_respawn_<nodes> for the nodes given). The
exit status is 1 only when a node printed a traceback: an impact missing is a figure.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import fault_rig  # noqa: E402
from results_file import recorded  # noqa: E402

from fmm_interfaces.srv import FitFriction  # noqa: E402
from fmm_ros.constants import FIT_SERVICE, FRICTION_TOPIC  # noqa: E402
from fmm_ros.core.signal.capture import CaptureConfig  # noqa: E402
from fmm_ros.io.bags.reader import BagReader  # noqa: E402
from fmm_ros.ros.graph import InProcessGraph  # noqa: E402
from fmm_ros.ros.launch import (  # noqa: E402
    SIMULATED_RIG,
    STATION,
)
from fmm_ros.workflows.replay import replay_bag  # noqa: E402

NODES = (*SIMULATED_RIG, STATION)
RESPAWNED = ('analyzer', 'fitter', 'recorder', 'station', 'hammer_sim', 'rig_sim')
RATE = 4.0  # x real time: 6 hits 8 s apart in 12 s of streaming
HITS_PER_LEVEL = 2
SPACING_S = 8.0
RESPAWN_SOURCE = ('silent_after_s=120.0',)
SESSION = (
    f'hammer_sim.hit_spacing_s={SPACING_S}',
    'hammer_sim.first_hit_s=1.0',
    'hammer_sim.batch_size=1000',
    'analyzer.window_s=6.0',
    'station.port=0',
    # A rig that respawns its nodes: the sources wait for an awaited consumer that went
    # silent (killed) until it is back.
    *(f'{source}.{name}' for source in ('hammer_sim', 'rig_sim') for name in RESPAWN_SOURCE),
)
IMPACT = re.compile(
    r'\[analyzer\]: impact (\d+) at sample (\d+): .*?, (accepted|rejected.*)$', re.M
)
LIVE_MU = re.compile(r'\[fitter\]: live mu (?:after|without) impact \d+', re.M)
DONE = 'session complete'
# What each node logs once it has started (a respawned one is waited for before the rig
# stops: a SIGINT while it still imports is a KeyboardInterrupt traceback).
STARTED = {
    'analyzer': ']: trigger ',
    'fitter': ' ready on ',
    'recorder': ']: recording ',
    'station': ']: station page on ',
    'hammer_sim': ' hits at ',
    'rig_sim': ']: plant m=',
}
TOOK_A_HIT = {'fitter': ']: live mu '}
"""What a node logs once it holds a hit: its kill waits for it, so the respawned node has
something to restore (a hit in flight at the kill is counted apart, as the known loss)."""
REPLAY_CAPTURE = CaptureConfig(
    window_s=6.0
)  # as the session's analyzer (`fmm replay --window-s 6`)
QUIET_S = 4.0  # the graph is quiet once no impact and no live mu came for this long


@dataclass
class Run:
    """What one respawn did, from the bags, the fitter's service and the logs."""

    node: str
    hits_sent: int = 0
    reported: set[int] = field(default_factory=set)  # impact ids the analyzer(s) logged
    accepted_live: set[int] = field(default_factory=set)
    held: set[int] = field(default_factory=set)
    counted: set[int] = field(default_factory=set)
    replayed: set[int] = field(default_factory=set)
    bags: int = 0
    restored: set[int] = field(default_factory=set)  # what a respawned fitter held again
    named: str = ''
    tracebacks: int = 0
    note: str = ''

    @property
    def checks(self) -> dict[str, bool]:
        """held, counted, replayed: every impact accepted live is in each."""
        live = self.accepted_live
        return {
            'held': bool(live) and live <= self.held,
            'counted': bool(live) and live <= self.counted,
            'replayed': bool(live) and live <= self.replayed,
        }

    def line(self) -> str:
        """One printed line: the counts and what is missing where."""
        live = self.accepted_live
        return (
            f'{self.node}: hits {self.hits_sent} sent, {len(self.reported)} reported, '
            f'{len(live)} accepted live; held {len(live & self.held)}, counted '
            f'{len(live & self.counted)}, replayed {len(live & self.replayed)} of them '
            f'({self.bags} bag{"s" if self.bags != 1 else ""}); '
            + (
                'ok'
                if all(self.checks.values())
                else 'MISSING '
                + ', '.join(
                    f'{name} {sorted(live - got)}'
                    for name, got in (
                        ('held', self.held),
                        ('counted', self.counted),
                        ('replayed', self.replayed),
                    )
                    if not live <= got
                )
            )
            + (f'; named: {self.named}' if self.named else '')
            + (f'; {self.tracebacks} tracebacks' if self.tracebacks else '')
            + (f'; {self.note}' if self.note else '')
        )


class Rig(fault_rig.Rig):
    """The six processes, one of them respawned, with their logs in one directory."""

    def __init__(self, work: Path, rate: float, hits_per_level: int) -> None:
        super().__init__(
            work,
            rate,
            hits_per_level,
            (f'fitter.state_dir={work / "fitter_state"}',),
            nodes=NODES,
            session=SESSION,
        )

    def wait_quiet(self, timeout_s: float) -> None:
        """Until no impact and no live mu has come for QUIET_S (or timeout_s passed)."""
        deadline = time.monotonic() + timeout_s
        seen, since = -1, time.monotonic()
        while time.monotonic() < deadline:
            analyzer, fitter = self.log('analyzer'), self.log('fitter')
            now = len(IMPACT.findall(analyzer)) + len(LIVE_MU.findall(fitter))
            if now != seen:
                seen, since = now, time.monotonic()
            elif time.monotonic() - since > QUIET_S:
                return
            time.sleep(0.2)


def fitted_ids(timeout_s: float = 60.0) -> tuple[set[int], str]:
    """The impacts the fitter holds and fits (every one: an empty request), and its message."""
    with InProcessGraph(domain_id=int(os.environ['ROS_DOMAIN_ID'])) as graph:
        from rclpy.node import Node

        node = graph.add(lambda **kwargs: Node('respawn_check', **kwargs))
        client = node.create_client(FitFriction, FIT_SERVICE)
        graph.start()
        request = FitFriction.Request()
        request.include_flagged = False
        response = graph.call(client, request, timeout_s=timeout_s)
    return set(int(i) for i in response.impact_ids), response.message


def bag_paths(rig: Rig) -> list[Path]:
    """Every bag the run's recorders wrote (`bag`, `bag_1`, ...)."""
    return sorted(
        (p for p in rig.work.glob('bag*') if p.is_dir()),
        key=lambda p: (len(p.name), p.name),
    )


def read_bags(rig: Rig, result: Run) -> None:
    """Accepted-live ids, the newest live mu's ids and the replay's accepted ids, from the bags."""
    newest: tuple[int, set[int]] = (-1, set())
    for path in bag_paths(rig):
        result.bags += 1
        with BagReader(path, strict=False) as reader:
            for msg in reader.impacts():
                if msg.accepted:
                    result.accepted_live.add(int(msg.impact_id))
            try:
                topic = reader.find(FRICTION_TOPIC, 'fmm_interfaces/msg/FrictionEstimate')
            except ValueError:
                topic = ''
            if topic:
                for stamp, msg in reader.decoded(topic, 'fmm_interfaces/msg/FrictionEstimate'):
                    if stamp >= newest[0]:
                        newest = (stamp, set(int(i) for i in msg.impact_ids))
    # The newest bag alone must replay the session: a respawned recorder copies the bag of
    # the one killed into its own.
    replay = replay_bag(bag_paths(rig)[-1], REPLAY_CAPTURE, threads=1)
    result.replayed = {r.impact_id for r in replay.summary.impacts if r.accepted}
    result.counted = newest[1]


def respawn_run(
    work: Path, node: str, rate: float = RATE, hits_per_level: int = HITS_PER_LEVEL
) -> Run:
    """One session with `node` killed and respawned after the analyzer's first report."""
    rig = Rig(work, rate, hits_per_level)
    result = Run(node)
    session_s = (1.0 + 3 * hits_per_level * SPACING_S) / rate
    try:
        rig.wait_for('hammer_sim', 'starting', 90.0)
        rig.wait_for('analyzer', '[analyzer]: impact ', 90.0)
        if node in TOOK_A_HIT:
            rig.wait_for(node, TOOK_A_HIT[node], 90.0)
        started = rig.log(node).count(STARTED[node])
        rig.respawn(node)
        deadline = time.monotonic() + 180.0
        while rig.log(node).count(STARTED[node]) <= started and time.monotonic() < deadline:
            time.sleep(0.2)
        rig.wait_for('hammer_sim', DONE, 120.0 + 4 * session_s)
        rig.wait_quiet(120.0)
        try:
            result.held, message = fitted_ids()
            if not result.held:
                result.note = f'fit refused: {message}'
        except TimeoutError as error:
            result.note = f'fit service: {error}'
    finally:
        rig.stop()
    logs = {path.stem: path.read_text(errors='replace') for path in rig.work.glob('*.log')}
    sent = re.findall(r'\((\d+) of (\d+) hits\)', logs.get('hammer_sim', ''))
    result.hits_sent = sum(int(hits) for hits, _ in sent)
    result.reported = {int(i) for i, _, _ in IMPACT.findall(logs.get('analyzer', ''))}
    result.tracebacks = sum(text.count('Traceback') for text in logs.values())
    named = [
        line.split(']: ', 1)[-1][:160]
        for text in logs.values()
        for line in text.splitlines()
        if any(text in line for text in ('joined an acquisition', 'restored', 'cannot be held'))
    ]
    result.named = ' | '.join(named[:3])
    for ids in re.findall(
        r'\[fitter\]: restored \d+ impacts .*?: ids \[([\d, ]*)\]', logs.get('fitter', '')
    ):
        result.restored |= {int(i) for i in ids.split(',') if i.strip()}
    read_bags(rig, result)
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='one fitter respawn (CI)')
    parser.add_argument('--runs', type=int, default=10)
    parser.add_argument('--nodes', nargs='+', choices=RESPAWNED)
    parser.add_argument('--rate', type=float, default=RATE)
    parser.add_argument('--hits-per-level', type=int, default=HITS_PER_LEVEL)
    args = parser.parse_args(argv)
    nodes = args.nodes or (['fitter'] if args.quick else list(RESPAWNED))
    runs = 1 if args.quick else args.runs
    root = Path(tempfile.mkdtemp(prefix='fmm_fault_respawn_'))
    failed = 0
    try:
        print(
            f'load {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; x{args.rate:g}, '
            f'{3 * args.hits_per_level} hits {SPACING_S:g} s apart',
            flush=True,
        )
        for node in nodes:
            counts = {'held': 0, 'counted': 0, 'replayed': 0}
            for k in range(runs):
                result = respawn_run(root / f'{node}_{k}', node, args.rate, args.hits_per_level)
                for name, ok in result.checks.items():
                    counts[name] += ok
                failed += result.tracebacks > 0  # a crash; a missing impact is a figure
                print(f'  run {k}: {result.line()}', flush=True)
            print(
                f'== {node} respawned: '
                + ', '.join(f'{name} {n} of {runs}' for name, n in counts.items())
                + f' (load {os.getloadavg()[0]:.2f})',
                flush=True,
            )
    finally:
        if os.environ.get('FMM_KEEP'):
            print(root)
        else:
            shutil.rmtree(root, ignore_errors=True)
    return 1 if failed else 0


def section(argv: list[str]) -> str:
    """The RESULTS.md section of a run: `fault_respawn`, or one per set of nodes named."""
    nodes = []
    for arg in argv[argv.index('--nodes') + 1 :] if '--nodes' in argv else []:
        if arg.startswith('-'):
            break
        nodes.append(arg)
    return '_'.join(['fault_respawn', *nodes])


if __name__ == '__main__':
    with recorded(section(sys.argv[1:]), quick='--quick' in sys.argv or '--runs' not in sys.argv):
        raise SystemExit(main())
