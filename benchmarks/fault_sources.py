"""Sources we did not write, into the analyzer as `ros2 run` starts it: what is lost.

Each case starts the analyzer as its own process (the package's params file) and
`benchmarks/foreign_source.py` as another: a plain rclpy publisher with no flow control, of
a simulated session (3 hits 3 s apart, 2 s records: 9 s of signal) at x1, x10, x50 or x100
real time in batches of 100, 500 or 5,000 samples, as a KEEP_ALL writer (it can be slowed)
or a KEEP_LAST depth-10 one (it cannot). The source publishes the session `--runs` times,
each a new acquisition it declares (index from 0, a new frame_id), into the same analyzer;
each run's figures are the differences of the analyzer's /diagnostics counts across it:

- samples sent per channel against those received, and what the analyzer counts lost (its
  ledger's missing samples, or the batches the middleware reported lost: never fewer);
- hits sent against hits reported on fmm/impacts (distinct trigger indices);
- what the analyzer named on /diagnostics above OK, and whether it named the source as one
  the flow control cannot hold back before its first batch.

A run is `clean` (nothing lost, every hit reported), `named` (what was lost is counted in
full and named on /diagnostics) or `LOST`. The other families, `--families`:

- `jump`: the index runs 1 batch, 10 batches or 10 s ahead within an acquisition (x10): the
  ledger must count exactly those samples missing and take no new acquisition;
- `two`: two sources (other node names and frame_ids) on the same topics, each run a new
  analyzer: both named in the log and on /diagnostics before the stream counts their damage;
- `damage`: NaN, an infinite sample and a stuck run, inside a record and between records
  (the 24 s session, 6 s records): named on /diagnostics and in the log, rate-limited.

    .venv/bin/python benchmarks/fault_sources.py [--quick] [--runs N] [--rates 1 10 50 100]
        [--batches 100 500 5000] [--history keep_all keep_last] [--families foreign jump two damage]

--quick: x100 in 500-sample batches, KEEP_LAST, two runs. A run given --runs writes its
printout into RESULTS.md, a section per family (and history: `fault_sources_keep_all`), so
they can run at once; others write nothing.
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

import numpy as np  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from results_file import recorded  # noqa: E402
from stress_rig import fresh_domain  # noqa: E402

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
    """What the analyzer publishes: impacts, and its /diagnostics (above OK, and its values)."""

    def __init__(self, node) -> None:
        self.triggers: set[int] = set()
        self.named: dict[str, str] = {}  # each status's last message above OK
        self.ever_named: set[str] = set()  # every such message seen
        self.values: dict[str, str] = {}  # the analyzer's newest value of each key
        self.changed_at = time.monotonic()
        self.warned_before_data: bool | None = None  # unpaced source named before its batches
        self._baseline_received = 0
        node.create_subscription(ImpactResult, IMPACTS_TOPIC, self._impact, RESULT_QOS)
        node.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, self._diag, DIAGNOSTICS_QOS)

    def new_run(self) -> None:
        """Forget the last run's hits and names; its counts stay the baseline of the next."""
        self.triggers.clear()
        self.named.clear()
        self.ever_named.clear()
        self.warned_before_data = None
        self._baseline_received = self.count('force received samples')

    def count(self, key: str) -> int:
        """The newest integer value of an analyzer key (0 before it was published)."""
        return int(self.values.get(key, 0))

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
                if kv.key.endswith(' received samples') and self.values.get(kv.key) != kv.value:
                    self.changed_at = time.monotonic()
                self.values[kv.key] = kv.value
        if self.warned_before_data is None and any(
            'without flow control' in s.message for s in msg.status if 'analyzer' in s.name
        ):
            self.warned_before_data = self.count('force received samples') == (
                self._baseline_received
            )


@dataclass
class Outcome:
    """One run's figures, from outside the analyzer."""

    rate: float
    batch: int
    sent: int
    received: dict[str, int] = field(default_factory=dict)
    said_missing: dict[str, int] = field(default_factory=dict)
    lost_batches: dict[str, int] = field(default_factory=dict)  # the message-lost event's
    resyncs: dict[str, int] = field(default_factory=dict)  # new acquisitions the stream took
    hits_sent: int = 0
    hits_reported: int = 0
    named: list[str] = field(default_factory=list)
    source_line: str = ''
    ever_named: list[str] = field(default_factory=list)
    warned_before_data: bool = False
    log: str = ''

    @property
    def lost(self) -> int:
        """Samples sent that the analyzer never received, both channels."""
        return sum(self.sent - got for got in self.received.values()) if self.received else -1

    def counted(self, quantity: str) -> int:
        """Samples of a channel the analyzer says it lost, the larger of its two counts.

        Its ledger's missing samples, and the batches the middleware reported lost (the same
        samples where later batches came; alone for a lost tail, which leaves the index no
        gap to show).
        """
        return max(
            self.said_missing.get(quantity, 0), self.lost_batches.get(quantity, 0) * self.batch
        )

    @property
    def undercounted(self) -> bool:
        """The analyzer says fewer lost than were lost on some channel."""
        return any(self.counted(q) < self.sent - got for q, got in self.received.items())

    @property
    def clean(self) -> bool:
        """Nothing lost, every hit reported."""
        return self.lost == 0 and self.hits_reported == self.hits_sent

    @property
    def verdict(self) -> str:
        """'clean', 'named' (a loss counted in full and named on /diagnostics), 'LOST'."""
        if self.clean:
            return 'clean'
        if self.named and not self.undercounted:
            return 'named'
        return 'LOST'

    def line(self) -> str:
        """One printed line of the run."""
        return (
            f'{self.verdict}; lost {self.lost} of {2 * self.sent} samples, analyzer counts '
            f'{sum(self.counted(q) for q in self.received)} (ledger '
            f'{sum(self.said_missing.values())} missing, '
            f'{sum(self.lost_batches.values())} batches lost in transport); hits '
            f'{self.hits_reported} of {self.hits_sent}; source: {self.source_line}'
            + (f'; named: {" | ".join(self.named)}' if self.named and not self.clean else '')
        )


@dataclass(frozen=True)
class Session:
    """The simulated session a foreign source publishes, and the analyzer's record length."""

    spacing_s: float = 8.0
    window_s: float = 6.0
    hits_per_level: int = 1
    seed: int = 3

    def samples_file(self, work: Path) -> Path:
        """The session's samples in an .npz for foreign_source.py (simulated once, here)."""
        path = work / 'session.npz'
        simulated = self.simulated()
        np.savez(
            path,
            force_n=simulated.force_n,
            velocity_m_s=simulated.velocity_m_s,
            sample_rate_hz=simulated.sample_rate_hz,
        )
        return path

    def simulated(self):
        """The simulated session."""
        return simulated_session(self.hits_per_level, spacing_s=self.spacing_s, seed=self.seed)


COUNTED_KEYS = ('received samples', 'missing samples', 'batches lost in transport')
SHORT = Session(spacing_s=3.0, window_s=2.0)
"""3 hits 3 s apart, 2 s records: a 9 s session, so x1 runs cost seconds, not minutes."""


def accounted(values: dict[str, str], quantity: str, batch: int) -> int:
    """Samples of a channel the analyzer received or counted lost, by its /diagnostics."""
    received, missing, lost_batches = (int(values.get(f'{quantity} {k}', 0)) for k in COUNTED_KEYS)
    return received + missing + lost_batches * batch


def run_series(
    work: Path,
    rate: float,
    batch: int,
    history: str,
    runs: int = 1,
    session: Session = Session(),
    settle_s: float = 6.0,
    extra: tuple[str, ...] = (),
    skipped: int = 0,
) -> list[Outcome]:
    """`runs` sessions of one foreign source process in turn into one analyzer process.

    Each run is its own acquisition (index from 0, a frame_id of its own, so the source
    declares it: `foreign_source.py --repeat`); its figures are the differences of the
    analyzer's /diagnostics counts across it, its hits those reported during it. extra:
    more arguments for foreign_source.py (`--damage`); skipped: samples of each channel the
    source skips (an index jump), which the analyzer counts missing besides what it lost.
    """
    fresh_domain()
    work.mkdir(parents=True)
    simulated = session.simulated()
    sent, hits = simulated.force_n.size, len(simulated.hit_levels)
    samples = session.samples_file(work)
    overrides = parse_overrides([f'analyzer.window_s={session.window_s}'], ['analyzer'])
    processes = start_processes(['analyzer'], default_params_file(), overrides, log_dir=work)
    outcomes = []
    try:
        with InProcessGraph(domain_id=int(os.environ['ROS_DOMAIN_ID'])) as graph:
            watch = Watch(graph.add(_node_factory('foreign_source_watch')))
            graph.start()
            deadline = time.monotonic() + 120
            while not watch.values and time.monotonic() < deadline:  # the analyzer is up
                time.sleep(0.1)
            source = subprocess.Popen(
                [
                    sys.executable,
                    str(HERE / 'foreign_source.py'),
                    f'--rate-factor={rate}',
                    f'--batch={batch}',
                    f'--history={history}',
                    '--frame-id=lab_daq',
                    f'--repeat={runs}',
                    '--linger-s=0.3',
                    f'--samples={samples}',
                    *extra,
                ],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=(work / 'source.log').open('w'),
                text=True,
            )
            for run in range(runs):
                watch.new_run()
                before = dict(watch.values)
                if run:
                    source.stdin.write('next\n')
                    source.stdin.flush()
                line = source.stdout.readline().strip()
                # The analyzer may still be working through its queue: wait until every
                # sample is received or counted lost and every hit reported, or it is quiet.
                watch.changed_at = time.monotonic()
                deadline = time.monotonic() + 300
                while time.monotonic() < deadline and (
                    time.monotonic() - watch.changed_at < settle_s
                ):
                    done = len(watch.triggers) >= hits and all(
                        accounted(watch.values, q, batch) - accounted(before, q, batch)
                        >= sent + skipped
                        for q in ('force', 'velocity')
                    )
                    if done:
                        time.sleep(1.2)  # one more /diagnostics: the counts' final values
                        break
                    time.sleep(0.1)
                outcome = Outcome(rate, batch, sent, hits_sent=hits)
                outcome.source_line = line or (work / 'source.log').read_text()[-300:]
                for quantity in ('force', 'velocity'):
                    for key, into in zip(
                        COUNTED_KEYS,
                        (outcome.received, outcome.said_missing, outcome.lost_batches),
                        strict=True,
                    ):
                        name = f'{quantity} {key}'
                        into[quantity] = watch.count(name) - int(before.get(name, 0))
                    name = f'{quantity} resyncs'
                    outcome.resyncs[quantity] = watch.count(name) - int(before.get(name, 0))
                outcome.hits_reported = len(watch.triggers)
                outcome.named = sorted(f'{k}: {v}' for k, v in watch.named.items())
                outcome.ever_named = sorted(watch.ever_named)
                outcome.warned_before_data = bool(watch.warned_before_data)
                outcomes.append(outcome)
            source.stdin.close()
            source.wait(timeout=60)
    finally:
        stop_processes(processes, nodes=['analyzer'])
    log = (work / 'analyzer.log').read_text(errors='replace')
    for outcome in outcomes:
        outcome.log = log
    return outcomes


def run_case(
    work: Path, rate: float, batch: int, history: str, extra: tuple[str, ...] = ()
) -> Outcome:
    """One foreign source (the 24 s session, 6 s records) into its own analyzer process."""
    return run_series(work, rate, batch, history, extra=extra)[0]


def two_sources_case(work: Path, rate: float = 10.0) -> tuple[list[str], str]:
    """Two foreign sources (other node names and frame_ids) on the same topics at once.

    Returns every message the analyzer published on /diagnostics above OK, and its log.
    """
    fresh_domain()
    work.mkdir(parents=True)
    samples = Session().samples_file(work)
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
                        f'--samples={samples}',
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


TWO_SOURCES = 'two sources publish /fmm/force: '


def two_sources_verdict(named: list[str], log: str) -> str:
    """'named', or what fell short of naming both publishers in time.

    Named: on /diagnostics and in the log, by node name or GID, before the stream counted
    any damage they did (within one batch).
    """
    said = [text for text in named if ': sources: ' in text and TWO_SOURCES in text]
    if not said:
        return 'NOT NAMED on /diagnostics'
    names = said[0].split(TWO_SOURCES)[1].split(';')[0].split(', ')
    if not all(n in {'/daq_one', '/daq_two'} or n.startswith('gid ') for n in names):
        return f'WRONG NAMES {names}'
    lines = log.splitlines()
    at = next((k for k, line in enumerate(lines) if TWO_SOURCES in line), None)
    if at is None:
        return 'NOT NAMED in the log'
    damage = [k for k, line in enumerate(lines) if 'refused' in line or 'never arrived' in line]
    if damage and damage[0] < at:
        return 'NAMED LATE (after the stream counted damage)'
    return 'named'


DAMAGE_WANTED = (
    'force: 25 NaN from sample 21000',  # 5 inside the first record, 20 between records
    '1 stuck run (501 samples) from sample 74999',  # between records
    'velocity: 1 infinite from sample 71000',  # between records
)


def damage_verdict(outcome: Outcome) -> str:
    """'named' when /diagnostics names every damage and the log does, rate-limited."""
    samples = [text for text in outcome.named if ': samples: ' in text]
    missing = [want for want in DAMAGE_WANTED if not samples or want not in samples[0]]
    if missing:
        return f'NOT NAMED on /diagnostics: {missing}'
    warnings = [line for line in outcome.log.splitlines() if 'damaged samples' in line]
    if not 1 <= len(warnings) <= 4:  # once per channel, then at most every 10 s
        return f'LOG {len(warnings)} lines'
    return 'named' if outcome.lost == 0 else f'named, but {outcome.lost} samples lost'


def _node_factory(name: str):
    from rclpy.node import Node

    return lambda **kwargs: Node(name, **kwargs)


def jump_verdict(outcome: Outcome, jump: int, run: int) -> str:
    """'counted' when a jump's samples are all missing and no new acquisition was taken.

    Each run of a series is a new acquisition its source declares (a new frame_id, index 0
    again): one resynchronisation each, the first run's excepted.
    """
    declared = 0 if run == 0 else 1
    if outcome.said_missing != {'force': jump, 'velocity': jump}:
        return f'MISCOUNTED (ledger says {outcome.said_missing} missing, {jump} skipped)'
    if any(n != declared for n in outcome.resyncs.values()):
        return f'NEW ACQUISITION GUESSED ({outcome.resyncs} resyncs, {declared} declared)'
    if outcome.lost or outcome.hits_reported != outcome.hits_sent:
        return f'counted, but {outcome.lost} samples lost, {outcome.hits_reported} hits'
    return 'counted'


def tally(verdicts: list[str]) -> str:
    """How often each verdict came, over the runs."""
    return ', '.join(f'{v} {verdicts.count(v)} of {len(verdicts)}' for v in sorted(set(verdicts)))


def load() -> str:
    one, five, _ = os.getloadavg()
    return f'load {one:.2f} {five:.2f}'


def arguments(argv: list[str] | None) -> argparse.Namespace:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true')
    parser.add_argument('--runs', type=int, default=1)
    parser.add_argument('--rates', type=float, nargs='+', default=[1, 10, 50, 100])
    parser.add_argument('--batches', type=int, nargs='+', default=[100, 500, 5000])
    parser.add_argument(
        '--history', choices=('keep_all', 'keep_last'), nargs='+', default=['keep_all', 'keep_last']
    )
    parser.add_argument(
        '--families',
        choices=('foreign', 'jump', 'two', 'damage'),
        nargs='+',
        default=['foreign'],
    )
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = arguments(argv)
    if args.quick:
        args.rates, args.batches, args.history = [100], [500], ['keep_last']
        args.runs, args.families = 2, ['foreign']
    root = Path(tempfile.mkdtemp(prefix='fmm_fault_sources_'))
    summary = []
    try:
        print(f'{load()}; {args.runs} runs a case, a foreign source process each')
        if 'foreign' in args.families:
            print(
                f'session: {SHORT.hits_per_level * 3} hits {SHORT.spacing_s:g} s apart, '
                f'{SHORT.window_s:g} s records; one analyzer process a case'
            )
        for history in args.history if 'foreign' in args.families else []:
            for rate in args.rates:
                for batch in args.batches:
                    case = f'{history} x{rate:g} batch {batch}'
                    outcomes = run_series(
                        root / f'{history}_x{rate:g}_{batch}',
                        rate,
                        batch,
                        history,
                        args.runs,
                        SHORT,
                    )
                    for run, outcome in enumerate(outcomes):
                        print(f'{case} run {run}: {outcome.line()}', flush=True)
                    verdicts = [o.verdict for o in outcomes]
                    lost = [o.lost for o in outcomes]
                    hits = sum(o.hits_reported for o in outcomes)
                    summary.append(
                        f'{case}: {tally(verdicts)}; samples lost per run max {max(lost)}, '
                        f'total {sum(lost)}; hits {hits} of {sum(o.hits_sent for o in outcomes)}; '
                        'source named unpaced on /diagnostics before its first batch: '
                        f'{"yes" if outcomes[0].warned_before_data else "NO"}; '
                        f'{load()}'
                    )
                    print('== ' + summary[-1], flush=True)
        if 'jump' in args.families:
            for jump in (500, 5000, 100_000):  # 1 batch, 10 batches, 10 s at 10 kHz
                outcomes = run_series(
                    root / f'jump_{jump}',
                    10.0,
                    500,
                    'keep_all',
                    args.runs,
                    SHORT,
                    extra=(f'--jump-samples={jump}',),
                    skipped=jump,
                )
                verdicts = [jump_verdict(o, jump, run) for run, o in enumerate(outcomes)]
                for run, verdict in enumerate(verdicts):
                    print(f'index jump {jump} run {run}: {verdict}', flush=True)
                summary.append(
                    f'index jump of {jump} samples within an acquisition (x10, 500-sample '
                    f'batches): {tally(verdicts)}; {load()}'
                )
                print('== ' + summary[-1], flush=True)
        if 'two' in args.families:
            verdicts = []
            for run in range(args.runs):
                named, log = two_sources_case(root / f'two_{run}')
                verdicts.append(two_sources_verdict(named, log))
                print(f'two sources run {run}: {verdicts[-1]}', flush=True)
            summary.append(f'two sources on one topic (x10): {tally(verdicts)}; {load()}')
            print('== ' + summary[-1], flush=True)
        if 'damage' in args.families:
            verdicts = []
            for run in range(args.runs):
                outcome = run_case(root / f'damage_{run}', 10.0, 500, 'keep_all', ('--damage',))
                verdicts.append(damage_verdict(outcome))
                print(f'damaged samples run {run}: {verdicts[-1]}', flush=True)
            summary.append(
                f'damaged samples (NaN, inf, stuck; inside and between records, x10): '
                f'{tally(verdicts)}; {load()}'
            )
            print('== ' + summary[-1], flush=True)
        print('\nsummary:\n' + '\n'.join(summary))
        print(load() + ' after')
    finally:
        if not os.environ.get('FMM_KEEP'):
            shutil.rmtree(root, ignore_errors=True)
        else:
            print(root)
    return 0


def section(argv: list[str]) -> str:
    """The RESULTS.md section of a run: one per family (and history), so they can run at once."""
    args = arguments(argv)
    parts = [*args.history] if 'foreign' in args.families else []
    return '_'.join(['fault_sources', *parts, *(f for f in args.families if f != 'foreign')])


if __name__ == '__main__':
    with recorded(section(sys.argv[1:]), quick='--quick' in sys.argv or '--runs' not in sys.argv):
        raise SystemExit(main())
