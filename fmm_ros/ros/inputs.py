"""A consumer node's force and velocity inputs: subscriptions into one stream, with its account.

The analyzer and the fitter take both channels the same way: each batch goes to their
`AlignedStream` owner (capture or history) under the core's stream rules, their progress goes
back to the sources (flow control), their ledger goes to /diagnostics, and their faults to
the log once per kind. The topic a batch arrives on says which channel it is; a batch whose
own `quantity` disagrees, or that is no sample batch at all, is refused and counted. The
response topic carries a velocity, an acceleration or a displacement (`RESPONSE_CHANNELS`):
the first batch's quantity is the sensor's (`response_quantity`), fed where the velocity goes,
and a later batch of another quantity is refused. Samples are converted to SI once, here,
from the batch's `unit` by the one unit table (`fmm_ros.units`); a unit it does not know is
refused by name (fault `unit`: ERROR on /diagnostics, one log line), never read as if it were SI.
Batches the middleware reports lost before this node could take them (a KEEP_LAST or
best-effort writer overwrote what it had not delivered: docs/explanation/reliability.md) are
counted per channel from the subscription's message-lost event: ERROR on /diagnostics (part
`transport`) and a log line, at most every 10 s, naming the topic and how many. Damaged
samples (NaN, infinite, a stuck run: `core.signal.sample_watch`) are named wherever they
fall, inside a hit's record or between records: WARN on /diagnostics (part `samples`) and a
log line when a channel first shows them, then at most every 10 s while they go on.
"""

import time
from collections.abc import Callable

from rclpy.callback_groups import CallbackGroup
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node

from fmm_interfaces.msg import SampleBatch
from fmm_ros.constants import FORCE, FORCE_TOPIC, RESPONSE_CHANNELS, VELOCITY, VELOCITY_TOPIC
from fmm_ros.core.signal.sample_watch import SampleWatch
from fmm_ros.core.signal.stream import AlignedStream, Batch
from fmm_ros.errors import UnitError
from fmm_ros.ros import msgs
from fmm_ros.ros.flow import ProgressReporter
from fmm_ros.ros.health import ERROR, OK, WARN, ChannelRate, FaultLog, Health, stream_status
from fmm_ros.ros.qos import SAMPLE_QOS
from fmm_ros.ros.sources import SourceCheck

LOST_LOG_REPEAT_S = 10.0  # at most one log line this often about batches lost in transport


class SampleInputs:
    """Subscribes force and velocity, feeds `take(quantity, batch)`, reports and accounts."""

    def __init__(
        self,
        node: Node,
        stream: AlignedStream,
        take: Callable[[str, Batch], None],
        health: Health,
        *,
        callback_group: CallbackGroup | None = None,
    ) -> None:
        self._node = node
        self._stream = stream
        self._take = take
        node.last_batch_at = 0.0  # a consumer of batches: drained before it stops
        self._rates: dict[str, ChannelRate] = {}
        self._faults = FaultLog(node)
        self.topics: dict[str, str] = {}
        self.response_quantity = VELOCITY.quantity
        """What the response sensor measures (from its first batch; velocity until then)."""
        self._response_known = False
        for channel, topic in ((FORCE, FORCE_TOPIC), (VELOCITY, VELOCITY_TOPIC)):
            subscription = node.create_subscription(
                SampleBatch,
                topic,
                lambda msg, quantity=channel.quantity: self._on_batch(quantity, msg),
                SAMPLE_QOS,
                callback_group=callback_group,
                event_callbacks=SubscriptionEventCallbacks(
                    message_lost=lambda info, quantity=channel.quantity: self._on_lost(
                        quantity, info.total_count_change
                    ),
                    matched=lambda info, quantity=channel.quantity: self._on_matched(
                        quantity, info.current_count
                    ),
                ),
            )
            self.topics[channel.quantity] = subscription.topic_name
        self.lost_batches: dict[str, int] = {}
        """Batches of each channel the middleware reported lost before this node took them."""
        self._lost_logged_at = -1e9
        self.reporter = ProgressReporter(
            node, list(self.topics.values()), max_skew_s=stream.rules.max_skew_s
        )
        self.sources = SourceCheck(node, self.topics, on_change=health.publish)
        health.add('stream', lambda: stream_status(stream.ledger, self._rates))
        health.add('sources', self.sources.status)
        health.add('transport', self.transport_status)
        self.samples = SampleWatch()
        """NaN, infinite and stuck samples of each channel, counted as they arrive."""
        self._damage_logged_at: dict[str, float] = {}
        health.add('samples', self.samples_status)

    def samples_status(self) -> tuple:
        """The `samples` part of /diagnostics: WARN once a channel showed a damaged sample."""
        damaged = {q: d for q, d in self.samples.damage.items() if d.any}
        values: dict[str, object] = {}
        for quantity, damage in self.samples.damage.items():
            values[f'{quantity} NaN samples'] = damage.nan_samples
            values[f'{quantity} infinite samples'] = damage.inf_samples
            values[f'{quantity} stuck runs'] = damage.stuck_runs
        if damaged:
            return WARN, '; '.join(d.summary(q) for q, d in damaged.items()), values
        return OK, 'no NaN, infinite or stuck sample', values

    def _watch_samples(self, quantity: str, batch: Batch) -> None:
        """Count a batch's damaged samples; log them, at most every LOST_LOG_REPEAT_S."""
        if not self.samples.watch(quantity, batch.first_sample_index, batch.samples):
            return
        now = time.monotonic()
        if now - self._damage_logged_at.get(quantity, -1e9) >= LOST_LOG_REPEAT_S:
            self._damage_logged_at[quantity] = now
            summary = self.samples.damage[quantity].summary(quantity)
            self._node.get_logger().warning(f'damaged samples: {summary}')

    def _on_matched(self, quantity: str, count: int) -> None:
        """A publisher of a channel matched or left (matched event)."""
        if hasattr(self, 'sources'):  # events may come before the check exists
            self.sources.matched(quantity, count)

    def _on_lost(self, quantity: str, count: int) -> None:
        """The middleware lost `count` batches of a channel on the way (message-lost event)."""
        self.lost_batches[quantity] = self.lost_batches.get(quantity, 0) + count
        now = time.monotonic()
        if now - self._lost_logged_at >= LOST_LOG_REPEAT_S:
            self._lost_logged_at = now
            self._node.get_logger().error(f'{self._lost_text()}: the publisher overwrote them')

    def _lost_text(self) -> str:
        return '; '.join(
            f'{count} batches lost on {self.topics[quantity]} before this node took them'
            for quantity, count in sorted(self.lost_batches.items())
        )

    def transport_status(self) -> tuple:
        """The `transport` part of /diagnostics: ERROR once the middleware lost a batch."""
        if self.lost_batches:
            return (
                ERROR,
                self._lost_text(),
                {f'{q} batches lost in transport': n for q, n in self.lost_batches.items()},
            )
        return OK, 'no batch lost in transport', {}

    def log_ledger(self) -> None:
        """Log each channel's ledger (a node does on stopping: its final account)."""
        for ledger in self._stream.ledger.values():
            self._node.get_logger().info(f'stopped: {ledger.summary()}')

    def _on_batch(self, quantity: str, msg: SampleBatch) -> None:
        self._node.last_batch_at = time.monotonic()
        self.sources.saw(quantity, msg.sample_rate_hz)
        detail = f'last from {msg.header.frame_id!r} at {msg.first_sample_index}'
        if quantity == VELOCITY.quantity and not self._response_known:
            if msg.quantity in {channel.quantity for channel in RESPONSE_CHANNELS}:
                self.response_quantity, self._response_known = msg.quantity, True
        expected = self.response_quantity if quantity == VELOCITY.quantity else quantity
        try:
            batch = msgs.si_stream_batch(msg, expected)
        except UnitError as error:  # refused by name: never read as if it were SI
            self._stream.refuse_malformed(quantity, len(msg.samples), kind='unit')
            detail = str(error)
        else:
            if msg.quantity != expected:
                self._stream.refuse_malformed(quantity, len(batch.samples))
            else:
                self._watch_samples(quantity, batch)
                try:
                    self._take(quantity, batch)
                except ValueError:  # not even a sample batch: counted, the stream unchanged
                    self._stream.refuse_malformed(quantity, len(batch.samples))
                else:
                    rate = self._rates.setdefault(quantity, ChannelRate())
                    rate.newest_stamp_ns = batch.stamp_ns
        next_index = self._stream.next_index(quantity)
        if next_index is not None:
            self.reporter.update(self.topics[quantity], next_index, self._stream.sample_rate_hz)
        self._faults.check(self._stream.ledger, detail)
