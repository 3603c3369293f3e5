"""A simulated rig session end to end through the real node graph, in one process.

hammer_sim -> rig_sim -> analyzer -> fitter, with the recorder writing everything to a bag:
the session's hits go through the same topics, QoS and services a lab uses, and its results
are taken from what the graph publishes (/fmm/impacts, /fmm/frf, the live mu on
/fmm/friction) and answers
(/fmm/fit_friction), never from inside the nodes: its report draws the fit service's answer
(`msgs.friction_result`), not a second fit. `fmm demo` and launch_scripts/sim_rig.py run it.
"""

import itertools
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.logging import LoggingSeverity
from rclpy.node import Node
from rclpy.parameter import Parameter

from fmm_interfaces.msg import FrfSummary, FrictionEstimate, ImpactResult
from fmm_interfaces.srv import DiagnoseModel, FitFriction
from fmm_ros.constants import (
    BATCH_SIZE,
    DIAGNOSE_SERVICE,
    DIAGNOSTICS_TOPIC,
    FIT_SERVICE,
    FRF_TOPIC,
    FRICTION_TOPIC,
    IMPACTS_TOPIC,
    SAMPLE_RATE_HZ,
)
from fmm_ros.core import results_schema as schema
from fmm_ros.core.identify.running import RunningEstimate
from fmm_ros.core.results_schema import ASCII_PM, format_with_uncertainty
from fmm_ros.core.signal.capture import CaptureConfig
from fmm_ros.core.signal.config import AnalysisConfig
from fmm_ros.io.bags.reader import BagReader
from fmm_ros.ros import msgs
from fmm_ros.ros.graph import InProcessGraph
from fmm_ros.ros.health import LEVEL_NAMES
from fmm_ros.ros.nodes import CONSUMERS
from fmm_ros.ros.nodes.analyzer import Analyzer
from fmm_ros.ros.nodes.fitter import Fitter
from fmm_ros.ros.nodes.hammer_sim import HammerSim
from fmm_ros.ros.nodes.recorder import Recorder
from fmm_ros.ros.nodes.rig_sim import RigSim
from fmm_ros.ros.qos import DIAGNOSTICS_QOS, RESULT_QOS
from fmm_ros.workflows.results import FrictionResult, hit_record, json_safe, level_record

# A session stops waiting when no new sample has gone out for this long (wall time) [s].
STALL_TIMEOUT_S = 60.0
# Wall-clock messages per second and channel an accelerated session aims at: rclpy costs
# about 0.1 ms CPU a message and more a wake-up, whatever the size, so larger batches at
# higher speed-ups keep the one-process graph ahead of its sources.
MESSAGES_PER_S = 100.0
# Longest batch [s of signal]: the analyzer declares samples missing once one channel runs
# more than max_skew_s (5 s) ahead of the other, so a batch must stay well inside that.
MAX_BATCH_S = 1.0


@dataclass
class SessionConfig:
    """What to run: the paper's protocol at a chosen speed, on a plant with known mu."""

    out_dir: Path
    hits_per_level: int = 10
    rate_factor: float = 100.0
    plant_mu: float = 0.113
    plant_effects: tuple[str, ...] = ()
    seed: int = 0
    # Samples per message; None picks one that keeps about MESSAGES_PER_S messages per
    # channel per second of wall time at the chosen rate_factor.
    batch_size: int | None = None
    params_file: Path | None = None
    # Write the session report (fmm_ros.report) from the recorded bag afterwards.
    report: bool = True

    def batch(self, sample_rate_hz: float = SAMPLE_RATE_HZ) -> int:
        """The batch size: given, or whole BATCH_SIZEs for ~MESSAGES_PER_S, at most MAX_BATCH_S."""
        if self.batch_size:
            return self.batch_size
        per_s = self.rate_factor * sample_rate_hz
        wanted = BATCH_SIZE * max(1, math.ceil(per_s / MESSAGES_PER_S / BATCH_SIZE))
        return min(wanted, int(MAX_BATCH_S * sample_rate_hz))


@dataclass
class DemoResult:
    """What the graph reported: per-impact results, level averages, the fit, the bag."""

    plant_mu: float
    hits_sent: int
    hits_reported: int
    hits_accepted: int
    levels: list[dict]
    r2: float
    friction: FrictionResult | None
    """The fit service's answer, None when it refused (fit_message says why)."""
    fit_message: str
    missing_effect: str
    diagnosis: str
    bag: str
    report: str
    """The report page (index.html) written from the bag, or '' when none was asked for."""
    wall_s: float
    """Wall time from the graph's start to the last impact reported [s]."""
    signal_s: float
    fit_s: float
    diagnose_s: float
    impacts: list[dict] = field(default_factory=list)
    running_mu: list[dict] = field(default_factory=list)
    """The fitter's live estimate after each accepted hit, as published on /fmm/friction."""
    health: list[dict] = field(default_factory=list)
    """Each node part's last status on /diagnostics: name, level, message."""
    ledger: dict[str, str] = field(default_factory=dict)
    """The recorder's ledger from the bag's metadata, one line a channel."""

    @property
    def fit_success(self) -> bool:
        """Whether the fit service answered with a fit."""
        return self.friction is not None

    @property
    def mu(self) -> float:
        """The fitted mu, NaN without a fit."""
        return self.friction.mu if self.friction else math.nan

    def as_json(self) -> dict:
        """The JSON summary `fmm demo --json` prints and writes to summary.json.

        The session's fields, then the fit as `FrictionResult.to_dict` gives it (mu, mu_stderr,
        per_file, ...; mu null when the service refused).
        """
        fields = {name: value for name, value in asdict(self).items() if name != 'friction'}
        fit = self.friction.to_dict() if self.friction else {'mu': None, 'mu_stderr': None}
        return json_safe({**fields, 'fit_success': self.fit_success, **fit})


class _Results(Node):
    """Listens to what the analyzer publishes, as any lab client would."""

    def __init__(
        self,
        on_impact: Callable[[ImpactResult], None],
        on_estimate: Callable[[RunningEstimate], None] = lambda _: None,
        **kwargs,
    ) -> None:
        super().__init__('session_results', **kwargs)
        self.impacts: list[ImpactResult] = []
        self.levels: dict[str, FrfSummary] = {}
        self.latest: FrfSummary | None = None  # its linearity covers every level so far
        self.estimates: list[RunningEstimate] = []
        self._on_impact = on_impact
        self._on_estimate = on_estimate
        self.create_subscription(ImpactResult, IMPACTS_TOPIC, self._impact, RESULT_QOS)
        self.create_subscription(FrfSummary, FRF_TOPIC, self._level, RESULT_QOS)
        self.create_subscription(FrictionEstimate, FRICTION_TOPIC, self._estimate, RESULT_QOS)
        self.health: dict[str, dict] = {}
        self.create_subscription(
            DiagnosticArray, DIAGNOSTICS_TOPIC, self._diagnostics, DIAGNOSTICS_QOS
        )
        self.fit = self.create_client(FitFriction, FIT_SERVICE)
        self.diagnose = self.create_client(DiagnoseModel, DIAGNOSE_SERVICE)

    def _impact(self, msg: ImpactResult) -> None:
        self.impacts.append(msg)
        self._on_impact(msg)

    def _level(self, msg: FrfSummary) -> None:
        self.levels[msg.level] = msg
        self.latest = msg

    def _estimate(self, msg: FrictionEstimate) -> None:
        estimate = msgs.running_estimate(msg)
        self.estimates.append(estimate)
        self._on_estimate(estimate)

    def _diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            self.health[status.name] = {
                'name': status.name,
                'level': LEVEL_NAMES.get(status.level, str(status.level)),
                'message': status.message,
            }


@dataclass
class _Session:
    """What the graph of a demo session published and answered, kept once it is torn down."""

    impacts: list[ImpactResult]
    levels: dict[str, FrfSummary]
    latest: FrfSummary | None
    estimates: list[RunningEstimate]
    fit: FitFriction.Response
    diagnosis: DiagnoseModel.Response
    hits_sent: int
    health: list[dict]
    capture: CaptureConfig
    analysis: AnalysisConfig
    wall_s: float
    signal_s: float
    fit_s: float
    diagnose_s: float


def run_demo_session(
    config: SessionConfig, progress: Callable[[str], None] = lambda _: None
) -> DemoResult:
    """Run the session to its last impact, fit mu over it, close the bag; return the results."""
    config.out_dir.mkdir(parents=True, exist_ok=True)
    bag = config.out_dir / 'bag'
    session = _run_graph(config, bag, progress)
    with BagReader(bag, strict=False) as reader:  # closed with the graph: its ledger is in
        ledger = {topic: entry.summary() for topic, entry in reader.recorded_ledger.items()}
    fit = session.fit
    friction = msgs.friction_result(fit) if fit.success else None
    page = ''
    if config.report:  # after the graph: the recorder has closed the bag
        progress(f'writing the session report to {config.out_dir / "report"}')
        page = str(
            _report(
                bag,
                config.out_dir / 'report',
                session.capture,
                session.analysis,
                config,
                friction,
                fit,
            )
        )
    return _demo_result(config, session, friction, str(bag), page, ledger)


def _run_graph(config: SessionConfig, bag: Path, progress: Callable[[str], None]) -> _Session:
    """Start the rig's nodes, run every hit, fit and diagnose over the services, tear down."""
    batch = config.batch()
    cli_args = (
        ['--ros-args', '--params-file', str(config.params_file)] if config.params_file else None
    )
    with InProcessGraph() as graph:
        hammer, analyzer, recorder = _add_rig(graph, config, batch, bag, cli_args)
        total = len(hammer.schedule)
        results = _add_results(graph, total, progress)
        for node in (hammer, analyzer):
            node.get_logger().set_level(LoggingSeverity.WARN)
        progress(
            f'{total} hits ({config.hits_per_level} a level) at x{config.rate_factor:g} '
            f'real time, {batch}-sample batches; recording to {bag}'
        )
        start = time.monotonic()
        graph.start()
        _wait(lambda: len(results.impacts) >= total, lambda: hammer.next_index)
        wall_s = time.monotonic() - start
        accepted = sum(msg.accepted for msg in results.impacts)
        _until(
            lambda: len(results.estimates) >= accepted,
            lambda: len(results.estimates),
            LIVE_MU_QUIET_S,
        )
        # The session is over: the hammer stops, and what it sent reaches the bag.
        hammer.hold()
        _wait(lambda: _recorded(recorder) >= hammer.next_index, lambda: _recorded(recorder))
        progress('session complete; fitting mu over the accepted impacts')
        fit = graph.call(results.fit, FitFriction.Request(), timeout_s=600.0)
        fit_s = time.monotonic() - start - wall_s
        chosen = _one_accepted_per_level(results.impacts)
        progress(f'diagnosing the model on impacts {chosen} (one a level)')
        diagnosis = graph.call(
            results.diagnose, DiagnoseModel.Request(impact_ids=chosen), timeout_s=600.0
        )
        diagnose_s = time.monotonic() - start - wall_s - fit_s
        return _Session(
            impacts=list(results.impacts),
            levels=dict(results.levels),
            latest=results.latest,
            estimates=list(results.estimates),
            fit=fit,
            diagnosis=diagnosis,
            hits_sent=hammer.hits_sent,
            health=sorted(results.health.values(), key=lambda status: status['name']),
            capture=analyzer.capture_config,
            analysis=analyzer.analysis_config,
            wall_s=wall_s,
            signal_s=hammer.next_index / hammer.config['sample_rate_hz'],
            fit_s=fit_s,
            diagnose_s=diagnose_s,
        )


def _add_rig(
    graph: InProcessGraph, config: SessionConfig, batch: int, bag: Path, cli_args: list | None
) -> tuple[HammerSim, Analyzer, Recorder]:
    """The simulated rig, the analyzer, the fitter and the recorder, added to graph."""

    def overrides(**values: object) -> list[Parameter]:
        return [Parameter(name, value=value) for name, value in values.items()]

    hammer = graph.add(
        HammerSim,
        cli_args=cli_args,
        parameter_overrides=overrides(
            hits_per_level=config.hits_per_level,
            rate_factor=config.rate_factor,
            batch_size=batch,
            seed=config.seed,
            wait_for_consumers=list(CONSUMERS['hammer_sim']),
        ),
    )
    graph.add(
        RigSim,
        cli_args=cli_args,
        parameter_overrides=overrides(
            mu=config.plant_mu,
            effects=list(config.plant_effects) or [''],
            seed=config.seed + 1,
            wait_for_consumers=list(CONSUMERS['rig_sim']),
        ),
    )
    analyzer = graph.add(Analyzer, cli_args=cli_args)
    graph.add(Fitter, cli_args=cli_args)
    recorder = graph.add(
        Recorder, cli_args=cli_args, parameter_overrides=overrides(bag_path=str(bag))
    )
    return hammer, analyzer, recorder


def _add_results(graph: InProcessGraph, total: int, progress: Callable[[str], None]) -> _Results:
    """The demo's listener, telling each impact and live mu estimate in words."""
    reported = itertools.count(1)  # ids are stable, not a count (stable_impact_id)
    return graph.add(
        _Results,
        on_impact=lambda msg: progress(
            f'impact {next(reported)}/{total} (id {msg.impact_id}): {msg.level or "no level"} '
            f'{msg.peak_force_n:.0f} N, {msg.impulse_n_s:.3f} N*s, '
            f'|X/F| {msg.peak_receptance_m_per_n * 1e3:.3f} mm/N at '
            f'{msg.natural_frequency_hz:.2f} Hz, '
            + ('accepted' if msg.accepted else f'rejected ({", ".join(msg.flags)})')
        ),
        on_estimate=lambda estimate: progress(
            f'live mu after {estimate.count} accepted: '
            f'{format_with_uncertainty(estimate.mu, estimate.mu_stderr, ASCII_PM)} '
            f'(one mu: p = {estimate.consistency_p_value:.3g})'
        ),
    )


def _demo_result(
    config: SessionConfig,
    session: _Session,
    friction: FrictionResult | None,
    bag: str,
    page: str,
    ledger: dict,
) -> DemoResult:
    """The DemoResult of a session's published results, fit and diagnosis."""
    impacts, latest, diagnosis, fit = (
        session.impacts,
        session.latest,
        session.diagnosis,
        session.fit,
    )
    ordered = sorted(session.levels.values(), key=lambda summary: summary.mean_impulse_n_s)
    return DemoResult(
        plant_mu=config.plant_mu,
        hits_sent=session.hits_sent,
        hits_reported=len(impacts),
        hits_accepted=sum(msg.accepted for msg in impacts),
        levels=[
            {
                'name': s.level,
                **level_record(s, schema.keys(schema.DEMO_LEVEL)),
            }
            for s in ordered
        ],
        r2=latest.linearity_r2 if latest else math.nan,
        friction=friction,
        fit_message=fit.message,
        missing_effect=diagnosis.missing_effect if diagnosis.success else '',
        diagnosis=diagnosis.verdict if diagnosis.success else diagnosis.message,
        bag=bag,
        report=page,
        wall_s=session.wall_s,
        signal_s=session.signal_s,
        fit_s=session.fit_s,
        diagnose_s=session.diagnose_s,
        impacts=[
            {
                **hit_record(m, schema.keys(schema.DEMO_IMPACT)),
                'flags': list(m.flags),
            }
            for m in impacts
        ],
        running_mu=[
            {
                'impact_id': e.impact_id,
                'count': e.count,
                'mu': e.mu,
                'mu_stderr': e.mu_stderr,
                'consistency_p_value': e.consistency_p_value,
                'levels': {level.level: [level.mu, level.mu_stderr] for level in e.levels},
            }
            for e in session.estimates
        ],
        health=session.health,
        ledger=ledger,
    )


def _report(
    bag: Path,
    out_dir: Path,
    capture,
    analysis,
    config: SessionConfig,
    friction: FrictionResult | None,
    fit: FitFriction.Response,
) -> Path:
    """The session report from the bag: analysed as the analyzer did, the fit service's mu."""
    from fmm_ros.report import build_report  # matplotlib: only when a report is asked for
    from fmm_ros.workflows.inputs import InputOptions
    from fmm_ros.workflows.replay import bag_impact_records
    from fmm_ros.workflows.session import SessionOptions, process_records

    records, problems = bag_impact_records(bag, capture)  # ids as the service's: one clock
    session = process_records(
        records,
        SessionOptions(inputs=InputOptions(capture=capture), analysis=analysis),
        friction=friction,
        fit_failure='' if friction else f'the fit service refused: {fit.message}',
        inputs=[str(bag)],
        problems=problems,
    )
    return build_report(
        session,
        out_dir,
        title=f'fmm demo: {config.hits_per_level} hits a level, plant mu {config.plant_mu}',
    )


LIVE_MU_QUIET_S = 10.0
"""The demo stops waiting for the live mu of the last hits when none came for this long (an
impact the fitter could not fit alone has none) [s]."""


def _recorded(recorder: Recorder) -> int:
    """The sample index both channels have reached in the recorder's ledger."""
    spans = [ledger.span for ledger in recorder.ledger.values()]
    return min((span[1] for span in spans if span), default=0) if len(spans) == 2 else 0


def _one_accepted_per_level(impacts: list[ImpactResult]) -> list[int]:
    """The last accepted impact of each level: a diagnosis sample spanning the levels."""
    chosen = {msg.level: msg.impact_id for msg in impacts if msg.accepted}
    return sorted(chosen.values())


def _wait(done: Callable[[], bool], samples_out: Callable[[], int]) -> None:
    """Wait until done(); give up if the source stops publishing for STALL_TIMEOUT_S."""
    if not _until(done, samples_out, STALL_TIMEOUT_S):
        raise TimeoutError(f'the session stalled: no samples published for {STALL_TIMEOUT_S:g} s')


def _until(done: Callable[[], bool], count: Callable[[], int], quiet_s: float) -> bool:
    """Wait until done() or until count() has not moved for quiet_s; whether done()."""
    last, moved = count(), time.monotonic()
    while not done():
        if time.monotonic() - moved > quiet_s:
            return False
        time.sleep(0.05)
        if count() != last:
            last, moved = count(), time.monotonic()
    return True
