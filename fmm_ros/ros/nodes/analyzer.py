"""analyzer: captures impacts from /fmm/force and /fmm/velocity and publishes their FRFs.

Both channels feed one `ImpactCapture`, which aligns them by `first_sample_index` (never by
arrival time) under the stream rules of the signal core: a missing batch is a gap that flags
the impact instead of computing a wrong FRF, a repeated or stray batch is refused and
counted, a restarted source is followed within one batch (the open record ends flagged
`interrupted`). Every completed record becomes an ImpactResult on fmm/impacts (accepted or
rejected, with its flags), stamped with the acquisition time of its trigger; the level
averages and the peak-receptance-vs-impulse law over all levels so far go out on fmm/frf,
one FrfSummary per level, transient-local for late subscribers. Health on /diagnostics.
Decisions about hits (fmm/impact_decisions) decide which hits the level averages
take, as they decide the fits (`summarize`): a decision republishes the levels.

An analyzer that joins an acquisition under way (respawned after a kill) never gets the
samples sent before: given `recorder_bag`, it reads that bag (the newest of `<bag_path>_<n>`,
which a respawned recorder fills with the whole session) once its stream is a record past
the join, in a worker thread. The hits the bag holds from before the join go back into the
level averages, and those no analyzer reported (under way at the kill, or while it was
down: the bag's fmm/impacts lacks them) are reported now, with the ids the live analyzer
would have given them.
"""

import dataclasses
import queue
import threading
import time
from collections import deque
from pathlib import Path
from typing import TYPE_CHECKING

from builtin_interfaces.msg import Time
from rclpy.node import Node

from fmm_interfaces.msg import FrfSummary, ImpactDecision, ImpactResult
from fmm_ros.constants import DECISIONS_TOPIC, FORCE, FRF_TOPIC, IMPACTS_TOPIC
from fmm_ros.core.settings import settings_of
from fmm_ros.core.signal.analysis import (
    AnalysisConfig,
    ImpactAnalysis,
    NominalLevel,
    Summary,
    analyze_impact,
    summarize,
)
from fmm_ros.core.signal.capture import FLAGS, CaptureConfig, ImpactCapture
from fmm_ros.core.signal.judging import Decision
from fmm_ros.core.signal.records import ImpactRecord, stable_impact_id
from fmm_ros.core.signal.response import as_measured
from fmm_ros.core.signal.stream import Batch
from fmm_ros.errors import BadInputError, FmmError
from fmm_ros.ros import msgs
from fmm_ros.ros.common import RESULT_QOS, run_node, shared_params
from fmm_ros.ros.health import OK, WARN, Health
from fmm_ros.ros.inputs import SampleInputs
from fmm_ros.ros.params import Param, declare_parameters, params_from
from fmm_ros.ros.qos import DECISION_QOS, IMPACT_QOS

if TYPE_CHECKING:
    from fmm_ros.workflows.replay import Missed

# How often a joined analyzer looks whether the recorder's bag holds what it missed, and for
# how long [s of wall time] (the recorder flushes about once a second, and may lag the
# stream by its flow window).
BAG_RETRY_S = 2.0
BAG_WAIT_S = 60.0

# The capture's and the FRFs' settings as declared in the core (`core.signal.config`), then
# the levels, which a params file gives as parallel lists.
PARAMS = (
    *params_from(CaptureConfig),
    *params_from(
        AnalysisConfig,
        ('band_limit_hz', 'peak_band_hz', 'force_window_s', 'exponential_decay_s'),
    ),
    *shared_params('level_names', 'level_peak_forces_n'),
    dataclasses.replace(params_from(NominalLevel, ('tolerance_n',))[0], name='level_tolerance_n'),
    *params_from(AnalysisConfig, ('reject_flags',)),
    Param(
        'keep_last_impacts',
        300,
        'Impacts kept for level averages and linearity [-]',
        limits=(1, 100_000),
        read_only=True,
    ),
    *shared_params('frame_id', 'recorder_bag'),
)


def configs_from_parameters(config: dict) -> tuple[CaptureConfig, AnalysisConfig]:
    """The core's capture and analysis configs from the analyzer's parameter values."""
    capture = CaptureConfig(**{item.name: config[item.name] for item in settings_of(CaptureConfig)})
    names = [name for name in config['level_names'] if name]
    peaks = config['level_peak_forces_n']
    if names and len(names) != len(peaks):
        raise BadInputError(
            f'level_names has {len(names)} entries but level_peak_forces_n has '
            f'{len(peaks)}: give one peak force per level'
        )
    unknown = sorted(set(config['reject_flags']) - set(FLAGS))
    if unknown:
        raise BadInputError(f'reject_flags: unknown flag(s) {unknown}; known: {list(FLAGS)}')
    if len(config['peak_band_hz']) != 2:
        raise BadInputError(f'peak_band_hz must be [low, high], got {config["peak_band_hz"]}')
    analysis = AnalysisConfig(
        band_limit_hz=config['band_limit_hz'],
        peak_band_hz=tuple(config['peak_band_hz']),
        force_window_s=config['force_window_s'] or None,
        exponential_decay_s=config['exponential_decay_s'] or None,
        levels=tuple(
            NominalLevel(name, peak, config['level_tolerance_n'])
            for name, peak in zip(names, peaks, strict=False)
        ),
        reject_flags=tuple(config['reject_flags']),
    )
    return capture, analysis


class Analyzer(Node):
    """Feeds both streams into the capture and publishes each completed impact's results."""

    def __init__(self, **kwargs) -> None:
        super().__init__('analyzer', **kwargs)
        self.config = declare_parameters(self, PARAMS)
        self.capture_config, self.analysis_config = configs_from_parameters(self.config)
        self.capture = ImpactCapture(self.capture_config)
        self.results: deque[ImpactAnalysis] = deque(maxlen=self.config['keep_last_impacts'])
        self.impacts_reported = 0
        self.impacts_accepted = 0
        self.joined_at_s = 0.0
        """Signal time at which this analyzer joined an acquisition under way (0: at its start)."""
        self.restored_from_bag = 0
        """Hits before the join taken from the recorder's bag (`recorder_bag`)."""
        self._joined_at = 0  # the join's sample index, and its acquisition's clock
        self._joined_origin_s: float | None = None
        self._bag_missed: queue.Queue[Missed | BaseException] = queue.Queue()
        self._bag_timer = None
        self._bag_thread: threading.Thread | None = None
        self._bag_deadline = 0.0
        self._bag_read = False  # the bag's hits are in (restored_from_bag says how many)
        self._impact_pub = self.create_publisher(ImpactResult, IMPACTS_TOPIC, IMPACT_QOS)
        self._frf_pub = self.create_publisher(FrfSummary, FRF_TOPIC, RESULT_QOS)
        self.decisions: dict[int, Decision] = {}
        self._last_stamp = Time()
        self.create_subscription(ImpactDecision, DECISIONS_TOPIC, self._on_decision, DECISION_QOS)
        health = Health(self)
        self.inputs = SampleInputs(self, self.capture.stream, self._on_batch, health)
        health.add('impacts', self._impacts_status)
        levels = (
            ', '.join(
                f'{level.name} {level.peak_force_n:g}+-{level.tolerance_n:g} N'
                for level in self.analysis_config.levels
            )
            or 'clustered'
        )
        self.get_logger().info(
            f'trigger {self.capture_config.trigger_level_n} N, window '
            f'{self.capture_config.window_s} s, levels: {levels}'
        )

    @property
    def ledger(self):
        """What each channel received, missed and refused."""
        return self.capture.ledger

    def _on_batch(self, quantity: str, batch: Batch) -> None:
        if not self.capture.stream.started and batch.first_sample_index > 0:
            self._joined(quantity, batch)
        for record in self.capture.feed_batch(quantity, batch):
            # One broken record is dropped, named once and on /diagnostics; the rest go on.
            with self.callback_faults.guard(
                f'impact at sample {record.trigger_sample_index} dropped'
            ):
                self._report(record, _trigger_stamp(record, batch))

    def _joined(self, quantity: str, batch: Batch) -> None:
        """The first batch is one of an acquisition under way: say so, and read the bag."""
        self.joined_at_s = batch.first_sample_index / batch.sample_rate_hz
        self._joined_at = batch.first_sample_index
        self._joined_origin_s = batch.origin_s
        bag = self.config['recorder_bag']
        self.get_logger().warning(
            f'joined an acquisition under way at sample {batch.first_sample_index} '
            f'({self.joined_at_s:.1f} s in, {quantity}): samples before it were not analysed '
            'here (a restart?); '
            + (
                f"the hits before it are read from the recorder's bag {bag}"
                if bag
                else 'an impact in them is not reported by this analyzer'
            )
        )
        if bag:
            self._bag_deadline = time.monotonic() + BAG_WAIT_S
            self._bag_timer = self.create_timer(BAG_RETRY_S, self._read_bag)

    def _read_bag(self) -> None:
        """Once the stream is a record past the join, read the bag (a worker's), then take it."""
        try:
            missed = self._bag_missed.get_nowait()
        except queue.Empty:
            missed = None
        if missed is None:
            if self._bag_thread is None or not self._bag_thread.is_alive():
                stream = self.capture.stream.next_index(FORCE.quantity) or 0
                after = self._joined_at + self._record_samples()
                if stream >= after or time.monotonic() > self._bag_deadline:  # or it stopped
                    self._bag_thread = threading.Thread(
                        target=self._bag_worker, name='recorder_bag', daemon=True
                    )
                    self._bag_thread.start()
            return
        if isinstance(missed, BaseException):
            self._bag_gave_up(f'{type(missed).__name__}: {missed}')
            return
        short = missed.reached < self._joined_at + self._record_samples()
        if short and time.monotonic() <= self._bag_deadline:
            return  # the recorder has not written that far yet: read again
        # Past the wait (the stream may have stopped), what the bag holds whole is taken.
        self.destroy_timer(self._bag_timer)
        self._take_missed(missed)
        self._bag_read = True

    def _record_samples(self) -> int:
        rate = self.capture.stream.sample_rate_hz or 0.0
        return int(round((self.capture_config.window_s + 1.0) * rate))

    def _bag_worker(self) -> None:
        # Imported here: rosbags and the replay cost a node's start-up nothing unless it joins.
        from fmm_ros.io.bags.backfill import bag_family
        from fmm_ros.workflows.replay import records_missed

        paths = bag_family(Path(self.config['recorder_bag']))
        try:
            if not paths:
                raise FileNotFoundError(f'no bag at {self.config["recorder_bag"]}')
            self._bag_missed.put(
                records_missed(
                    paths[-1],
                    self.capture_config,
                    joined_at=self._joined_at,
                    origin_s=self._joined_origin_s,
                )
            )
        except (OSError, ValueError) as error:
            self._bag_missed.put(error)

    def _bag_gave_up(self, why: str) -> None:
        """The bag cannot be read: said once, and the node goes on with what it has."""
        self.destroy_timer(self._bag_timer)
        self.get_logger().error(
            f"the recorder's bag {self.config['recorder_bag']} cannot give the hits before "
            f'the join ({why}): a hit in them is not reported by this analyzer'
        )

    def _take_missed(self, missed: 'Missed') -> None:
        """The bag's hits before the join into the averages; those never reported, reported."""
        live = list(self.results)
        self.results.clear()
        fresh = []
        for record in missed.records:
            result = analyze_impact(  # capture_records made each whole (`as_measured`)
                record,
                self.capture_config,
                self.analysis_config,
                impact_id=stable_impact_id(record),
            )
            self.results.append(result)
            if result.impact_id not in missed.reported_ids:
                fresh.append((result, record))
        self.results.extend(live)
        self.restored_from_bag = len(missed.records)
        summary = summarize(list(self.results), self.analysis_config, self.decisions)
        judged = {impact.impact_id: impact for impact in summary.impacts}
        for result, record in fresh:
            impact = judged.get(result.impact_id, result)
            stamp = _trigger_stamp(record, None)
            self.impacts_reported += 1
            self.impacts_accepted += impact.accepted
            self._impact_pub.publish(
                msgs.impact_result_msg(impact, stamp=stamp, frame_id=self.config['frame_id'])
            )
            self._log_impact(impact, 'from the bag, ')
        self._publish_levels(summary)
        self.get_logger().info(
            f"read the recorder's bag: {len(missed.records)} hits before the join back in the "
            f'level averages, {len(fresh)} of them never reported before, reported now'
        )

    def _impacts_status(self) -> tuple:
        last = self.results[-1] if self.results else None
        joined = ''
        if self.joined_at_s and self._bag_read:
            joined = (
                f'; joined the acquisition {self.joined_at_s:.1f} s in (a respawn?): '
                f"{self.restored_from_bag} hits before it read from the recorder's bag"
            )
        elif self.joined_at_s:
            joined = (
                f'; joined the acquisition {self.joined_at_s:.1f} s in (a respawn?): a hit '
                'before that, or under way then, is not reported here (the bag has it)'
            )
        return (
            WARN if joined else OK,
            f'{self.impacts_reported} reported, {self.impacts_accepted} accepted{joined}',
            {
                'impacts reported': self.impacts_reported,
                'impacts accepted': self.impacts_accepted,
                'open records': self.capture.open_impacts,
                'last impact': (
                    f'{last.impact_id} at {last.trigger_sample_index}: {last.level or "no level"}'
                    if last
                    else 'none'
                ),
            },
        )

    def _report(self, record: ImpactRecord, stamp: Time) -> None:
        """Analyse one completed record, publish it and the updated level summaries."""
        try:
            measured = as_measured(record, self.inputs.response_quantity, self.capture_config)
            result = analyze_impact(
                measured,
                self.capture_config,
                self.analysis_config,
                impact_id=stable_impact_id(record),
            )
        finally:
            self.capture.recycle(record)
        self.results.append(result)
        summary = summarize(list(self.results), self.analysis_config, self.decisions)
        judged = summary.impacts[-1]
        self.impacts_reported += 1
        self.impacts_accepted += judged.accepted
        self._impact_pub.publish(
            msgs.impact_result_msg(judged, stamp=stamp, frame_id=self.config['frame_id'])
        )
        self._last_stamp = stamp
        self._publish_levels(summary)
        self._log_impact(judged)

    def _log_impact(self, judged: ImpactAnalysis, where: str = '') -> None:
        verdict = 'accepted' if judged.accepted else f'rejected ({", ".join(judged.flags)})'
        self.get_logger().info(
            f'impact {judged.impact_id} at sample {judged.trigger_sample_index}: {where}'
            f'{judged.level or "no level"}, peak {judged.peak_force_n:.0f} N, impulse '
            f'{judged.impulse_n_s:.3f} N*s, |X/F| {judged.peak_receptance_m_per_n:.3e} m/N '
            f'at {judged.natural_frequency_hz:.2f} Hz, {verdict}'
        )

    def _publish_levels(self, summary: Summary) -> None:
        """Each level's average and the linearity law, stamped with the newest impact."""
        for level in summary.levels:
            self._frf_pub.publish(
                msgs.frf_summary_msg(
                    level,
                    summary.linearity,
                    stamp=self._last_stamp,
                    frame_id=self.config['frame_id'],
                )
            )

    def _on_decision(self, msg: ImpactDecision) -> None:
        """A decision about a hit held: the level averages again, without or with it."""
        try:
            decision = msgs.decision(msg)
        except FmmError as error:
            self.get_logger().error(f'decision about impact {msg.impact_id} ignored: {error}')
            return
        self.decisions[decision.impact_id] = decision
        if any(result.impact_id == decision.impact_id for result in self.results):
            self._publish_levels(
                summarize(list(self.results), self.analysis_config, self.decisions)
            )

    def destroy_node(self) -> None:
        """Log the final ledger of its inputs before the node goes."""
        self.inputs.log_ledger()
        super().destroy_node()


def _trigger_stamp(record: ImpactRecord, batch: Batch | None) -> Time:
    """Acquisition time of the trigger sample by its acquisition's clock (else the batch's).

    The fitter tells by it which acquisition a reported impact belongs to.
    """
    origin_s = record.acquisition_origin_s
    if origin_s is None:
        return msgs.time_msg(batch.stamp_ns if batch is not None else 0)
    return msgs.time_msg(
        round((origin_s + record.trigger_sample_index / record.sample_rate_hz) * 1e9)
    )


def main(args: list[str] | None = None) -> int:
    """`ros2 run fmm_ros analyzer`."""
    return run_node(Analyzer, args)


if __name__ == '__main__':
    main()
