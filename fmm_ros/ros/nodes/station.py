"""station: the operator's page, and the judge of hits.

Serves a page on http://127.0.0.1:8080/ (`host`, `port`): the force and velocity streams of
the last seconds, each hit as the analyzer reports it (its FRF at once; its pulse and its
decay with the model at the current mu once its record is cut from the station's own stream
history, as the fitter cuts it), each level's coherence as its average builds, progress per
level with advice ("softer", "harder"), the running mu, /diagnostics and the recording state,
the accept/reject buttons and the session metadata form (`fmm_ros.station`).

Judging: the fmm/judge_impact service (and the page's buttons, through the same check) turn
a decision about a hit the station has seen into an ImpactDecision on fmm/impact_decisions,
which the fitter applies and the recorder records. `judge_mode` says who judges a new hit:
`flags` (the analyzer's flags stand), `manual` (each hit is held `pending` until the
operator decides) or `function` (`judge_function`, a user's `module:function`, is called
with the hit's ImpactRecord and its ImpactResult message). Only hits published after the
station started are judged by it, so a restarted station never overrules what an operator
decided before. The session metadata goes out on fmm/session_info.

The station only watches: it reports no progress to the sources, so a slow page or a slow
station never holds the rig back (a batch the station misses is a gap in its display only).
A hit's figures (the model run over its decay, milliseconds, but seconds the first time,
while numba compiles) and a judge function (a user's code) run in a worker thread, so the
next hit reaches the page at once whatever they cost.
"""

import queue
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node

from fmm_interfaces.msg import (
    FrfSummary,
    FrictionEstimate,
    ImpactDecision,
    ImpactResult,
    SampleBatch,
    SessionInfo,
)
from fmm_interfaces.srv import JudgeImpact
from fmm_ros.constants import (
    DECISIONS_TOPIC,
    DIAGNOSTICS_TOPIC,
    FORCE,
    FORCE_TOPIC,
    FRF_TOPIC,
    FRICTION_TOPIC,
    IMPACTS_TOPIC,
    JUDGE_SERVICE,
    SESSION_INFO_TOPIC,
    VELOCITY,
    VELOCITY_TOPIC,
)
from fmm_ros.core.signal.history import SampleHistory
from fmm_ros.core.signal.judging import Decision, judge_with, load_judge
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.errors import BadInputError, FmmError
from fmm_ros.io import session_info
from fmm_ros.ros import msgs
from fmm_ros.ros.common import RIG_PARAMS, rig_from_parameters, run_node, shared_params
from fmm_ros.ros.cutting import ImpactCutter
from fmm_ros.ros.health import LEVEL_NAMES, OK, WARN, Health
from fmm_ros.ros.nodes.analyzer import PARAMS as ANALYZER_PARAMS
from fmm_ros.ros.params import Param, declare_parameters, params_from
from fmm_ros.ros.qos import (
    DECISION_QOS,
    DIAGNOSTICS_QOS,
    IMPACT_QOS,
    RESULT_QOS,
    SESSION_INFO_QOS,
    VIEW_SAMPLE_QOS,
)
from fmm_ros.ros.settings import StationSettings
from fmm_ros.station.server import StationServer
from fmm_ros.station.state import Level, StationState

# The levels and the rest velocity as the analyzer has them (one declaration; the params file
# gives both nodes the same values).
_SHARED = ('level_names', 'level_peak_forces_n', 'level_tolerance_n', 'rest_velocity_m_s')

PARAMS = (
    *RIG_PARAMS,
    *(param for param in ANALYZER_PARAMS if param.name in _SHARED),
    *shared_params('host', 'port'),
    *params_from(StationSettings),
    Param(
        'target_hits_per_level',
        10,
        'Hits a level needs (progress, and the level the operator aims at next) [-]',
        limits=(1, 10_000),
        read_only=True,
    ),
    Param(
        'stream_window_s',
        10.0,
        'The streams shown: the last this many seconds [s]',
        limits=(0.5, 120.0),
        read_only=True,
    ),
    Param(
        'stream_period_s',
        0.25,
        'How often the streams shown are updated [s]',
        limits=(0.05, 10.0),
        read_only=True,
    ),
    *shared_params('history_s'),
)


class Station(Node):
    """Feeds the page's state from the rig's topics; judges hits; publishes the metadata."""

    def __init__(self, **kwargs) -> None:
        super().__init__('station', **kwargs)
        self.config = cfg = declare_parameters(self, PARAMS)
        self.mode = cfg['judge_mode']
        self.judge_function = None
        if self.mode == 'function':
            self.judge_function = load_judge(cfg['judge_function'])
        names = [name for name in cfg['level_names'] if name]
        self.state = StationState(
            [
                Level(name, peak, cfg['level_tolerance_n'])
                for name, peak in zip(names, cfg['level_peak_forces_n'], strict=False)
            ],
            target_hits=cfg['target_hits_per_level'],
            mode=self.mode,
            rig=rig_from_parameters(cfg),
            rest_velocity_m_s=cfg['rest_velocity_m_s'],
        )
        self.started_ns = time.time_ns()
        self.history = SampleHistory(cfg['history_s'])
        self.cutter = ImpactCutter(self.history, self.get_logger())
        self._auto_judge: set[int] = set()  # hits published after the start, to judge
        self._records: queue.Queue[tuple[ImpactResult, ImpactRecord] | None] = queue.Queue()
        self._worker = threading.Thread(target=self._draw_hits, name='station_hits', daemon=True)
        self._worker.start()
        self._decisions_pub = self.create_publisher(ImpactDecision, DECISIONS_TOPIC, DECISION_QOS)
        self._session_pub = self.create_publisher(SessionInfo, SESSION_INFO_TOPIC, SESSION_INFO_QOS)
        for channel, topic in ((FORCE, FORCE_TOPIC), (VELOCITY, VELOCITY_TOPIC)):
            self.create_subscription(
                SampleBatch,
                topic,
                lambda msg, quantity=channel.quantity: self._on_batch(quantity, msg),
                VIEW_SAMPLE_QOS,
            )
        self.create_subscription(ImpactResult, IMPACTS_TOPIC, self._on_impact, IMPACT_QOS)
        self.create_subscription(FrfSummary, FRF_TOPIC, self.state.on_level, RESULT_QOS)
        self.create_subscription(
            FrictionEstimate, FRICTION_TOPIC, self.state.on_friction, RESULT_QOS
        )
        self.create_subscription(ImpactDecision, DECISIONS_TOPIC, self._on_decision, DECISION_QOS)
        self.create_subscription(
            SessionInfo, SESSION_INFO_TOPIC, self._on_session, SESSION_INFO_QOS
        )
        self.create_subscription(
            DiagnosticArray, DIAGNOSTICS_TOPIC, self._on_diagnostics, DIAGNOSTICS_QOS
        )
        self.create_service(JudgeImpact, JUDGE_SERVICE, self._on_judge)
        self.server = StationServer(
            cfg['host'],
            cfg['port'],
            self.state.snapshot,
            {'judge': self._judge_request, 'session': self._session_request},
            self.get_logger().warning,
        )
        try:
            self.server.start()
        except OSError as error:  # a second station, or another server, on the port
            self.get_logger().warning(
                f'port {cfg["port"]} on {cfg["host"]} cannot be used ({error}): '
                'serving on a free port instead'
            )
            self.server.port = 0
            self.server.start()
        self.state.emit = self.server.hub.broadcast
        self.create_timer(cfg['stream_period_s'], self._show_streams)
        health = Health(self)
        health.add('station', self._status)
        self.get_logger().info(
            f'station page on {self.server.url} (judging: {self.mode}'
            + (f' by {cfg["judge_function"]}' if self.judge_function else '')
            + ')'
        )

    # -- the rig's topics ---------------------------------------------------------------------

    def _on_batch(self, quantity: str, msg: SampleBatch) -> None:
        try:
            self.history.feed_batch(quantity, msgs.stream_batch(msg))
        except ValueError:
            self.history.stream.refuse_malformed(quantity, len(msg.samples))
            return
        for cut in self.cutter.batch_fed():
            self._records.put(cut)

    def _on_impact(self, msg: ImpactResult, info: dict) -> None:
        self.state.on_impact(msg)
        if info.get('source_timestamp', 0) >= self.started_ns:
            self._auto_judge.add(int(msg.impact_id))
            if self.mode == 'manual':
                self._publish(
                    Decision(
                        int(msg.impact_id),
                        'pending',
                        'station',
                        'manual mode: waiting for the operator',
                        self.mode,
                        int(msg.trigger_sample_index),
                        time.time_ns(),
                    )
                )
        for cut in self.cutter.impact(msg):
            self._records.put(cut)

    def _draw_hits(self) -> None:
        """Worker thread: each cut hit's figures, and its judgement in function mode.

        Stops at the None `destroy_node` puts in.
        """
        while (cut := self._records.get()) is not None:
            self._on_record(*cut)

    def _on_record(self, msg: ImpactResult, record: ImpactRecord) -> None:
        self.state.on_record(int(msg.impact_id), record)
        if self.judge_function is not None and int(msg.impact_id) in self._auto_judge:
            self._auto_judge.discard(int(msg.impact_id))
            self._publish(
                judge_with(
                    self.judge_function,
                    self.config['judge_function'],
                    record,
                    msg,
                    impact_id=int(msg.impact_id),
                    trigger_sample_index=int(msg.trigger_sample_index),
                    stamp_ns=time.time_ns(),
                )
            )

    def _on_decision(self, msg: ImpactDecision) -> None:
        try:
            self.state.on_decision(msgs.decision(msg))
        except FmmError as error:
            self.get_logger().error(f'a malformed decision was not shown: {error}')

    def _on_session(self, msg: SessionInfo) -> None:
        try:
            self.state.on_session(session_info.from_message(msg))
        except FmmError as error:
            self.get_logger().error(f'session metadata not shown: {error}')

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        self.state.on_diagnostics(
            [(s.name, LEVEL_NAMES.get(s.level, str(s.level)), s.message) for s in msg.status]
        )

    def _show_streams(self) -> None:
        """The last stream_window_s of both channels to the pages (none connected: nothing)."""
        rate = self.history.sample_rate_hz
        if not self.server.hub.clients or rate is None:
            return
        length = round(self.config['stream_window_s'] * rate)
        first_f, force = self.history.recent(FORCE.quantity, length)
        first_v, velocity = self.history.recent(VELOCITY.quantity, length)
        first = max(first_f, first_v)
        self.state.on_stream(first, rate, force[first - first_f :], velocity[first - first_v :])

    # -- judging and metadata -----------------------------------------------------------------

    def judge(
        self, impact_id: object, verdict: object, decided_by: object, reason: object
    ) -> Decision:
        """Decide about a hit the station has seen; the decision goes out.

        BadInputError names what is wrong (an unknown hit, a verdict, a name or reason missing
        or too long).
        """
        if isinstance(impact_id, bool) or not isinstance(impact_id, int):
            raise BadInputError(f'decision refused: impact id {impact_id!r} is not an integer')
        row = self.state.known(impact_id)
        if row is None:
            seen = sorted(self.state.hits)
            raise BadInputError(
                f'decision refused: impact {impact_id} is not a hit this station has seen '
                f'({f"ids {seen[0]}..{seen[-1]}" if seen else "none yet"})'
            )
        decision = Decision(
            impact_id,
            verdict,
            decided_by,
            reason if reason is not None else '',
            self.mode,
            row['trigger'],
            time.time_ns(),
        )
        self._publish(decision)
        return decision

    def _publish(self, decision: Decision) -> None:
        self._decisions_pub.publish(msgs.decision_msg(decision))
        self.get_logger().info(f'{decision.describe()} [{decision.mode} mode]')

    def _on_judge(
        self, request: JudgeImpact.Request, response: JudgeImpact.Response
    ) -> JudgeImpact.Response:
        try:
            decision = self.judge(
                int(request.impact_id), request.verdict, request.decided_by, request.reason
            )
        except FmmError as error:
            self.get_logger().warning(str(error))
            response.success, response.message = False, str(error)
            return response
        response.success, response.message = True, decision.describe()
        return response

    def _judge_request(self, body: dict) -> str:
        """The page's accept/reject: {impact_id, verdict, decided_by, reason}."""
        unknown = sorted(set(body) - {'impact_id', 'verdict', 'decided_by', 'reason'})
        if unknown:
            raise BadInputError(f'decision refused: unknown field(s) {unknown}')
        return self.judge(
            body.get('impact_id'), body.get('verdict'), body.get('decided_by'), body.get('reason')
        ).describe()

    def _session_request(self, body: dict) -> str:
        """The page's metadata form: every field checked, then published (and recorded)."""
        info = session_info.validated(body)
        self._session_pub.publish(
            msgs.session_info_msg(info, stamp=self.get_clock().now().to_msg())
        )
        self.get_logger().info(f'session metadata: {session_info.to_json(info)}')
        return 'session metadata saved: ' + (
            ', '.join(f'{label} {text}' for label, text in session_info.describe(info))
            or 'nothing entered'
        )

    # -- health and teardown ------------------------------------------------------------------

    def _status(self) -> tuple:
        clients = len(self.server.hub.clients)
        return (
            WARN if self.server.hub.dropped else OK,
            f'page on {self.server.url}, {clients} page(s) open, {len(self.state.hits)} hits seen',
            {
                'url': self.server.url,
                'pages open': clients,
                'pages dropped for lagging': self.server.hub.dropped,
                'judge mode': self.mode,
                'hits seen': len(self.state.hits),
                'hits waiting for samples': len(self.cutter.waiting),
            },
        )

    def destroy_node(self) -> None:
        """Stop the hits' worker and serving the page (open pages retry until one is back)."""
        self._records.put(None)
        self._worker.join()
        self.server.stop()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """`ros2 run fmm_ros station`."""
    return run_node(Station, args)


if __name__ == '__main__':
    main()
