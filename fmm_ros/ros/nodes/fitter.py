"""fitter: the fmm/fit_friction and fmm/diagnose_model services over the analyzer's impacts.

The fitter keeps the recent force and velocity streams itself (`SampleHistory`, sized from the
batches' own rate, under the same stream rules as the analyzer) and cuts each impact the
analyzer reports on fmm/impacts out of them by sample index, keeping the last
`keep_last_impacts`; an impact stamped with another acquisition's clock (the source restarted
in between) is not cut from this one's samples. So no record travels over a service, a bag
played into the graph is fitted like a live session, and the analyzer stays a pure stream
processor. Impacts are taken by the signal core's `select_impacts`: those the analyzer
flagged and rejected are left out and named in the response's message unless the request
sets include_flagged. A request that cannot be answered (no impacts yet, unknown ids, no
clean impact, a record friction cannot explain) gets success = false and the reason, never
a number. An impact named more than once in a request counts once (the message says so);
requests queue without limit and are answered in order (SERVICE_QOS). A held impact is never
replaced by another with its id.

After every accepted impact it also fits that impact alone and publishes the running mu (the
impacts' own mus, inverse-variance weighted: `core.identify.running`) on fmm/friction, so the
lab sees mu converge while the session runs.

Decisions about hits (fmm/impact_decisions: the operator's or a judge function's)
overrule the flags in both: a fit request takes the impacts `select_impacts` takes under
them, and the live mu drops a rejected impact (a new estimate, without its id) and takes an
accepted one back.

Given a `state_dir`, each held impact (its record, what the analyzer said about it, its live
fit) is written there as it is held (`io.held_impacts`), and a fitter started on it (a
respawn after SIGKILL) holds them again and publishes the live mu over them at once. A
reported impact whose samples never reached this fitter (a record open at a kill, or sent
while it was down) is cut from the recorder's bag when `recorder_bag` names it (the launcher
sets it from the recorder's bag_path; `cutting.ImpactCutter`); one that cannot be cut from
either is named in the log and WARN on /diagnostics. The history also serves fmm/recall_samples
(`fmm_ros.ros.recall`): a recorder respawned after a kill stores from it what was sent while
it was down.

Service callbacks run in their own callback group, so under `ros2 run` (a multi-threaded
executor) the streams keep flowing while a fit runs.
"""

import queue
import threading
from collections import Counter, OrderedDict
from dataclasses import dataclass
from pathlib import Path

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from fmm_interfaces.msg import FrictionEstimate, ImpactDecision, ImpactResult
from fmm_interfaces.srv import DiagnoseModel, FitFriction
from fmm_ros.constants import (
    DECISIONS_TOPIC,
    DIAGNOSE_SERVICE,
    FIT_SERVICE,
    FRICTION_TOPIC,
    IMPACTS_TOPIC,
)
from fmm_ros.core.diagnose.workflow import diagnose
from fmm_ros.core.identify.friction import fit_friction
from fmm_ros.core.identify.running import RunningEstimate, RunningFriction
from fmm_ros.core.identify.spec import MU_BOUNDS, FitSpec
from fmm_ros.core.results_schema import ASCII_PM, format_with_uncertainty
from fmm_ros.core.signal.analysis import ImpactSelection, select_impacts
from fmm_ros.core.signal.history import SampleHistory
from fmm_ros.core.signal.judging import Decision, is_taken
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.core.signal.response import as_measured
from fmm_ros.core.signal.stream import Batch
from fmm_ros.errors import BadInputError, FitError
from fmm_ros.io.held_impacts import (
    StoredImpact,
    forget_impact,
    load_impacts,
    save_impact,
    save_live_fit,
)
from fmm_ros.ros import msgs
from fmm_ros.ros.common import RIG_PARAMS, rig_from_parameters, run_node, shared_params
from fmm_ros.ros.cutting import BAG_RETRY_S, ImpactCutter
from fmm_ros.ros.health import OK, WARN, Health
from fmm_ros.ros.inputs import SampleInputs
from fmm_ros.ros.params import Param, declare_parameters, params_from
from fmm_ros.ros.qos import DECISION_QOS, IMPACT_QOS, RESULT_QOS
from fmm_ros.ros.recall import RecallServer
from fmm_ros.workflows.results import FrictionResult

PARAMS = (
    *RIG_PARAMS,
    # In a continuous session a hit finds the rig where friction stopped the last one.
    *params_from(FitSpec(fit_initial_position=True), ('fit_initial_position', 'chain_starts')),
    Param(
        'live_mu',
        True,
        f'After every accepted impact, fit it alone (in a worker thread) and publish the running '
        f'mu on {FRICTION_TOPIC}',
        read_only=True,
    ),
    Param(
        'keep_last_impacts',
        60,
        'Impact records held for fitting [-]',
        limits=(1, 10_000),
        read_only=True,
    ),
    *shared_params('history_s', history_s=120.0),
    Param(
        'state_dir',
        '',
        'Directory where each held impact is kept (its record and live fit, one file each), '
        'so a fitter killed and respawned holds them again; "" keeps them in memory only',
        read_only=True,
    ),
    *shared_params('recorder_bag'),
)


# Requests queue without limit and are answered in order, one at a time: rclpy's default
# service queue (keep last 10) dropped 9 of 20 clients asking at once, who then waited for
# ever.
SERVICE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_ALL,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)


@dataclass(frozen=True)
class HeldImpact:
    """An analyzer-reported impact and its record, cut from the history."""

    impact_id: int
    level: str
    accepted: bool
    flags: tuple[str, ...]
    record: ImpactRecord
    stamp_ns: int = 0  # ImpactResult.header.stamp: signal time of the trigger


class Fitter(Node):
    """Holds the reported impacts' records and answers fit requests on them."""

    def __init__(self, **kwargs) -> None:
        super().__init__('fitter', **kwargs)
        self.config = declare_parameters(self, PARAMS)
        cfg = self.config
        self.rig = rig_from_parameters(cfg)
        self.history = SampleHistory(cfg['history_s'])
        self.cutter = ImpactCutter(
            self.history,
            self.get_logger(),
            from_bags=Path(cfg['recorder_bag']) if cfg['recorder_bag'] else None,
        )
        self.impacts: OrderedDict[int, HeldImpact] = OrderedDict()
        self.last_fit = ''
        self.live_mu = ''
        self._lock = threading.Lock()  # impacts: written by the stream group, read by services
        streams = MutuallyExclusiveCallbackGroup()
        health = Health(self)
        self.inputs = SampleInputs(
            self, self.history.stream, self._on_batch, health, callback_group=streams
        )
        # A respawned recorder fills the stretch it was down from this history.
        self.recall = RecallServer(
            self,
            self.history,
            self.inputs.topics,
            lambda: self.inputs.response_quantity,
            callback_group=streams,
        )
        health.add('fits', self._fits_status)
        if self.cutter.from_bags is not None:
            self.create_timer(BAG_RETRY_S, self._cut_from_bags, callback_group=streams)
        self.create_subscription(
            ImpactResult, IMPACTS_TOPIC, self._on_impact, IMPACT_QOS, callback_group=streams
        )
        self.decisions: dict[int, Decision] = {}
        self.create_subscription(
            ImpactDecision,
            DECISIONS_TOPIC,
            self._on_decision,
            DECISION_QOS,
            callback_group=streams,
        )
        self._friction_pub = self.create_publisher(FrictionEstimate, FRICTION_TOPIC, RESULT_QOS)
        self._running = RunningFriction()
        # Each live-fitted impact's own (level, mu, stderr): put back when accepted again.
        self._own_fits: dict[int, tuple[str, float, float]] = {}
        self._to_fit: queue.Queue[HeldImpact | None] = queue.Queue()
        self.state_dir = Path(cfg['state_dir']) if cfg['state_dir'] else None
        self._state_failed = ''
        restored = self._restore() if self.state_dir else 0
        self._worker = None
        if cfg['live_mu']:
            self._worker = threading.Thread(target=self._fit_live, name='live_mu', daemon=True)
            self._worker.start()
            if restored:
                self._requeue_restored()
        services = MutuallyExclusiveCallbackGroup()
        self.create_service(
            FitFriction,
            FIT_SERVICE,
            self._on_fit,
            qos_profile=SERVICE_QOS,
            callback_group=services,
        )
        self.create_service(
            DiagnoseModel,
            DIAGNOSE_SERVICE,
            self._on_diagnose,
            qos_profile=SERVICE_QOS,
            callback_group=services,
        )
        self.get_logger().info(
            f'{FIT_SERVICE} and {DIAGNOSE_SERVICE} ready on '
            f'm={self.rig.mass_kg} kg, k={self.rig.stiffness_n_per_m} N/m, '
            f'N={self.rig.normal_force_n:.3f} N'
        )

    # -- streams ----------------------------------------------------------------------------

    def _on_batch(self, quantity: str, batch: Batch) -> None:
        self.history.feed_batch(quantity, batch)
        for msg, record in self.cutter.batch_fed():
            self._hold(msg, record)

    def _cut_from_bags(self) -> None:
        for msg, record in self.cutter.cut_from_bags():
            self._hold(msg, record)

    def _on_impact(self, msg: ImpactResult) -> None:
        with self._lock:
            known = self.impacts.get(msg.impact_id)
        if known is not None and known.record.trigger_sample_index == msg.trigger_sample_index:
            return  # held already (restored, or heard again from a respawned analyzer)
        for cut, record in self.cutter.impact(msg):
            self._hold(cut, record)

    def _fits_status(self) -> tuple:
        with self._lock:
            held = list(self.impacts.values())
        lost = self.cutter.not_held
        return (
            WARN if lost else OK,
            f'{len(held)} impacts held ({sum(i.accepted for i in held)} accepted); '
            + (
                f'{len(lost)} reported but not held (their samples never reached this '
                f'fitter, or were no longer held: ids {lost[-10:]}; '
                + ('the bag has them); ' if self.cutter.from_bags is None else 'nor the bag); ')
                if lost
                else ''
            )
            + (self.last_fit or 'no fit yet'),
            {
                'impacts held': len(held),
                'accepted held': sum(i.accepted for i in held),
                'impacts waiting for samples': len(self.cutter.waiting),
                'impacts waiting for the bag': len(self.cutter.for_bags),
                'impacts not held': len(lost),
                'history s': self.history.history_s,
                'state dir': (
                    f'{self.state_dir} ({self._state_failed or "written"})'
                    if self.state_dir
                    else 'none'
                ),
                'last fit': self.last_fit or 'none',
                'live mu': self.live_mu or 'none',
            },
        )

    def _hold(self, msg: ImpactResult, record: ImpactRecord) -> None:
        """Hold a reported impact's record (the last keep_last_impacts); fit it live."""
        held = HeldImpact(
            msg.impact_id,
            msg.level,
            msg.accepted,
            tuple(msg.flags),
            as_measured(record, self.inputs.response_quantity),
            msgs.stamp_ns(msg.header.stamp),
        )
        with self._lock:
            known = self.impacts.get(msg.impact_id)
            if known is not None:  # held impacts are never overwritten
                if known.record.trigger_sample_index != msg.trigger_sample_index:
                    self.get_logger().error(
                        f'impact {msg.impact_id} at sample {msg.trigger_sample_index} has '
                        f'the id of the impact held at {known.record.trigger_sample_index}:'
                        ' not held (the held one is kept)'
                    )
                return
            self.impacts[msg.impact_id] = held
            dropped = []
            while len(self.impacts) > self.config['keep_last_impacts']:
                dropped.append(self.impacts.popitem(last=False)[0])
        self._keep(held, dropped)
        if self._worker is not None and self._taken(held):
            self._to_fit.put(held)

    # -- state kept on disk (a respawn) ------------------------------------------------------

    def _restore(self) -> int:
        """Hold again the impacts a fitter before this one kept in state_dir; how many."""
        try:
            self.state_dir.mkdir(parents=True, exist_ok=True)
            stored, refused = load_impacts(self.state_dir)
        except OSError as error:
            self._state_lost(error)
            return 0
        for text in refused:
            self.get_logger().error(f'state_dir: {text}: not restored')
        stored = stored[-self.config['keep_last_impacts'] :]
        for impact in stored:
            self.impacts[impact.impact_id] = HeldImpact(
                impact.impact_id,
                impact.level,
                impact.accepted,
                impact.flags,
                impact.record,
                impact.stamp_ns,
            )
            if impact.live_fit is not None:
                self._own_fits[impact.impact_id] = impact.live_fit
        if stored:
            self.get_logger().warning(
                f'restored {len(stored)} impacts held before this fitter started, from '
                f'{self.state_dir} ({sum(i.accepted for i in stored)} accepted, '
                f'{len(self._own_fits)} with their live fit): ids '
                f'{[impact.impact_id for impact in stored]}'
            )
        return len(stored)

    def _requeue_restored(self) -> None:
        """The live mu over the restored impacts: their own fits, or fitted again."""
        estimate = None
        with self._lock:
            held = list(self.impacts.values())
            for impact in held:
                own = self._own_fits.get(impact.impact_id)
                if own is not None and self._taken(impact):
                    estimate = self._running.add(impact.impact_id, *own)
        if estimate is not None:
            self._publish_estimate(estimate)
        for impact in held:
            if impact.impact_id not in self._own_fits and self._taken(impact):
                self._to_fit.put(impact)

    def _keep(self, held: HeldImpact, dropped: list[int]) -> None:
        """Write a newly held impact to state_dir, and forget those no longer held."""
        if self.state_dir is None or self._state_failed:
            return
        try:
            save_impact(
                self.state_dir,
                StoredImpact(
                    held.impact_id,
                    held.level,
                    held.accepted,
                    held.flags,
                    held.stamp_ns,
                    held.record,
                ),
            )
            for impact_id in dropped:
                forget_impact(self.state_dir, impact_id)
        except OSError as error:
            self._state_lost(error)

    def _state_lost(self, error: OSError) -> None:
        """state_dir cannot be written (full, read-only, gone): said once, held in memory."""
        self._state_failed = f'{type(error).__name__}: {error}'
        self.get_logger().error(
            f'state_dir {self.state_dir}: {self._state_failed}; impacts are held in memory '
            'only from here on (a respawn would not hold them again)'
        )

    # -- decisions --------------------------------------------------------------------------

    def _taken(self, held: HeldImpact) -> bool:
        return is_taken(held.impact_id, held.accepted, self.decisions)

    def _on_decision(self, msg: ImpactDecision) -> None:
        """Apply one decision: fits take it from now on, the live mu drops or takes the hit."""
        try:
            decision = msgs.decision(msg)
        except ValueError as error:
            self.get_logger().error(f'decision about impact {msg.impact_id} ignored: {error}')
            return
        with self._lock:
            self.decisions[decision.impact_id] = decision
            held = self.impacts.get(decision.impact_id)
        self.get_logger().info(f'{decision.describe()}')
        if held is None or self._worker is None:
            return
        taken = self._taken(held)
        with self._lock:
            own = self._own_fits.get(held.impact_id)
            if not taken and held.impact_id in self._running:
                estimate = self._running.remove(held.impact_id)
            elif taken and own is not None and held.impact_id not in self._running:
                estimate = self._running.add(held.impact_id, *own)
            else:
                estimate = None
        if estimate is not None:
            self._publish_estimate(estimate)
        elif taken and own is None:
            self._to_fit.put(held)

    # -- live mu ----------------------------------------------------------------------------

    def _fit_live(self) -> None:
        """Worker thread: fit each accepted impact alone, publish the running estimate.

        Off the executor, so a fit (tens of ms) never holds up the streams; rclpy publishers
        may be used from another thread. Stops at the None `destroy_node` puts in.
        """
        while (held := self._to_fit.get()) is not None:
            try:
                fit = fit_friction(
                    [held.record],
                    rig=self.rig,
                    fit_initial_position=self.config['fit_initial_position'],
                )
                with self._lock:
                    if held.impact_id in self._own_fits or not self._taken(held):
                        continue  # fitted twice over, or rejected while it was fitted
                    estimate = self._running.add(held.impact_id, held.level, fit.mu, fit.mu_stderr)
                    self._own_fits[held.impact_id] = (held.level, fit.mu, fit.mu_stderr)
                if self.state_dir is not None and not self._state_failed:
                    try:
                        save_live_fit(
                            self.state_dir, held.impact_id, held.level, fit.mu, fit.mu_stderr
                        )
                    except OSError as error:
                        self._state_lost(error)
            except ValueError as error:  # FitError included: the impact adds nothing
                self.get_logger().warning(f'live mu: impact {held.impact_id} not used: {error}')
                continue
            self._publish_estimate(estimate)

    def _publish_estimate(self, estimate: RunningEstimate) -> None:
        """The running mu on fmm/friction, and in the log and the health status."""
        # Stamped in signal time, as the impact it follows; a decision's estimate follows no
        # new impact and takes the node's clock.
        with self._lock:
            held = self.impacts.get(estimate.impact_id)
        stamp = (
            msgs.time_msg(held.stamp_ns)
            if held is not None and held.stamp_ns and estimate.impact_id in estimate.impact_ids
            else self.get_clock().now().to_msg()
        )
        self._friction_pub.publish(msgs.friction_estimate_msg(estimate, stamp=stamp))
        self.live_mu = (
            f'{format_with_uncertainty(estimate.mu, estimate.mu_stderr, ASCII_PM)} over '
            f'{estimate.count} impacts '
            f'(one mu: p = {estimate.consistency_p_value:.3g})'
        )
        change = 'after' if estimate.impact_id in estimate.impact_ids else 'without'
        self.get_logger().info(f'live mu {change} impact {estimate.impact_id}: {self.live_mu}')

    def destroy_node(self) -> None:
        """Stop the live-mu worker (after the fit it is in), log the inputs' final ledger."""
        if self._worker is not None:
            self._to_fit.put(None)
            self._worker.join()
            self._worker = None
        self.inputs.log_ledger()
        super().destroy_node()

    # -- services ---------------------------------------------------------------------------

    def selected(
        self, impact_ids: list[int], include_flagged: bool = False
    ) -> tuple[list[HeldImpact], ImpactSelection]:
        """The impacts a request takes, by `select_impacts` over those it names (empty: all held).

        ValueError says why none can be taken: an id not held, or no clean impact (naming the
        flagged ones).
        """
        with self._lock:
            held = list(self.impacts.values())
        by_id = {impact.impact_id: impact for impact in held}
        if impact_ids:
            impact_ids = list(dict.fromkeys(impact_ids))  # an id named twice counts once
            missing = [i for i in impact_ids if i not in by_id]
            if missing:
                raise BadInputError(
                    f'impacts {missing} are not held (held: '
                    f'{sorted(by_id) or "none"}; the fitter keeps the last '
                    f'{self.config["keep_last_impacts"]})'
                )
            held = [by_id[i] for i in impact_ids]
        elif not held:
            raise BadInputError(f'no impact held yet ({len(self.cutter.waiting)} still arriving)')
        with self._lock:
            decisions = dict(self.decisions)
        selection = select_impacts(held, include_flagged=include_flagged, decisions=decisions)
        return [by_id[i] for i in selection.chosen], selection

    def _on_fit(
        self, request: FitFriction.Request, response: FitFriction.Response
    ) -> FitFriction.Response:
        try:
            impacts, selection = self.selected(list(request.impact_ids), request.include_flagged)
            bounds = (request.mu_min, request.mu_max) if request.mu_max > 0 else MU_BOUNDS
            fit = fit_friction(
                [impact.record for impact in impacts],
                rig=self.rig,
                fit_damping=request.fit_damping,
                mu_bounds=bounds,
                misfit=request.misfit or 'time',
                fit_initial_position=self.config['fit_initial_position'],
                chain_starts=selection.chained(self.config['chain_starts']),
            )
        except FitError as error:
            return _refused(response, f'{error.reason}: {error}')
        except ValueError as error:
            return _refused(response, str(error))
        result = FrictionResult.from_fit(fit, [impact.impact_id for impact in impacts])
        msgs.fill_fit_response(response, result)
        for note in (selection.note, repeated_note(request.impact_ids)):
            if note:
                response.message = f'{response.message}; {note}'
        self.last_fit = response.message
        self.get_logger().info(response.message)
        return response

    def _on_diagnose(
        self, request: DiagnoseModel.Request, response: DiagnoseModel.Response
    ) -> DiagnoseModel.Response:
        """Name the effect the base model misses in the requested impacts."""
        try:
            impacts, selection = self.selected(list(request.impact_ids), request.include_flagged)
            result = diagnose(
                [impact.record for impact in impacts],
                rig=self.rig,
                fit_initial_position=self.config['fit_initial_position'],
                chain_starts=selection.chained(self.config['chain_starts']),
            )
        except FitError as error:
            return _refused(response, f'{error.reason}: {error}')
        except ValueError as error:
            return _refused(response, str(error))
        self.get_logger().info(f'diagnosis of {len(impacts)} impacts: {result.verdict}')
        response = msgs.fill_diagnose_response(response, result)
        for note in (selection.note, repeated_note(request.impact_ids)):
            if note:
                response.message = f'{response.message}; {note}'
        return response


def repeated_note(impact_ids) -> str:
    """What a request named more than once ('' if nothing): each such impact counts once."""
    counts = Counter(impact_ids)
    repeated = [f'{impact_id} ({count} times)' for impact_id, count in counts.items() if count > 1]
    return f'impacts named more than once, counted once: {", ".join(repeated)}' if repeated else ''


def _refused(response: object, reason: str) -> object:
    response.success = False
    response.message = reason
    return response


def main(args: list[str] | None = None) -> int:
    """`ros2 run fmm_ros fitter`: two threads, so fits do not stall the streams."""
    return run_node(Fitter, args, threads=2)


if __name__ == '__main__':
    main()
