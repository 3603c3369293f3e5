"""Samples recalled from a node's history, so a respawned recorder's bag holds the session whole.

A recorder killed and started again copies its predecessor's bag into its own
(`nodes.recorder`), but what the sources sent while no recorder ran reached no bag: at x4,
one or two hits a respawn replayed from no bag at all. The fitter still holds those samples
(its `SampleHistory`, `history_s` long). It serves them on fmm/recall_samples
(`RecallServer`). The respawned recorder asks for each channel's gap between the copy's end
and the first batch it hears live (`GapRecall`), and holds that channel's live batches until
the answer comes or `RECALL_WAIT_S` passes. So the bag stores every batch in index order, and
its ledger counts missing only what neither the bag nor the history held. Nothing is
invented: what the history never received (NaN there) stays missing, and a history of
another acquisition (its clock differs) is not stored.
"""

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from rclpy.callback_groups import CallbackGroup
from rclpy.node import Node
from rclpy.serialization import serialize_message

from fmm_interfaces.msg import SampleBatch
from fmm_interfaces.srv import RecallSamples
from fmm_ros.constants import FORCE, RECALL_SERVICE, RESPONSE_CHANNELS, Channel
from fmm_ros.core.signal.history import SampleHistory
from fmm_ros.core.signal.stream import DEFAULT_RULES
from fmm_ros.ros import msgs

RECALL_WAIT_S = 10.0
"""How long a recorder holds a channel's live batches for the recall's answer [s]: a respawn
takes seconds, and the sources run on meanwhile (the held batches are in memory, reported
taken)."""
RECALL_BATCH = 1000
"""Samples in a recalled batch at most (100 ms at 10 kHz: the size of a live one)."""


class RecallServer:
    """Answers fmm/recall_samples from a history the node feeds (the fitter's)."""

    def __init__(
        self,
        node: Node,
        history: SampleHistory,
        topics: dict[str, str],
        response_quantity: Callable[[], str],
        *,
        callback_group: CallbackGroup | None = None,
    ) -> None:
        """Serve `history`'s channels by topic (`topics`: quantity -> resolved topic name).

        Give the callback group that feeds the history: the ring is not thread-safe.
        `response_quantity` says what the response channel measures (velocity until known).
        """
        self._history = history
        self._quantities = {topic: quantity for quantity, topic in topics.items()}
        self._response_quantity = response_quantity
        node.create_service(
            RecallSamples, RECALL_SERVICE, self._on_request, callback_group=callback_group
        )

    def _on_request(
        self, request: RecallSamples.Request, response: RecallSamples.Response
    ) -> RecallSamples.Response:
        quantity = self._quantities.get(request.topic)
        first, end = int(request.first_sample_index), int(request.end_sample_index)
        if quantity is None:
            response.message = (
                f'{request.topic} is not held here: this node takes '
                f'{", ".join(sorted(self._quantities))}'
            )
            return response
        if end <= first:
            response.message = (
                f'end_sample_index {end} must be above first_sample_index {first} '
                '(the span is [first, end))'
            )
            return response
        history = self._history
        runs = history.held(quantity, first, end)
        if not runs:
            response.message = (
                f'samples {first}..{end} of {request.topic} are not held (the history holds '
                f'{history.capacity} samples up to {history.next_index(quantity)}, from '
                f'{history.first_index} of this acquisition)'
            )
            return response
        channel = self._channel(quantity)
        rate, origin_s = history.sample_rate_hz, history.origin_s
        stream = history.stream
        for start, values in runs:
            for offset in range(0, len(values), RECALL_BATCH):
                index = start + offset
                stamp_ns = 0 if origin_s is None else round((origin_s + index / rate) * 1e9)
                response.batches.append(
                    msgs.sample_batch(
                        values[offset : offset + RECALL_BATCH],
                        quantity=channel,
                        sample_rate_hz=rate,
                        first_sample_index=index,
                        stamp=msgs.time_msg(stamp_ns),
                        frame_id=stream.sender(quantity),
                        full_scale=stream.full_scale(quantity),
                    )
                )
        held = sum(len(values) for _, values in runs)
        response.success = True
        response.message = f'{held} of the {end - first} samples asked for are held'
        return response

    def _channel(self, quantity: str) -> Channel:
        """The SI channel (quantity, unit) a held quantity's samples are in."""
        if quantity == FORCE.quantity:
            return FORCE
        response = self._response_quantity()
        return next(channel for channel in RESPONSE_CHANNELS if channel.quantity == response)


@dataclass
class _Gap:
    """A channel's stretch the copy lacks, and what the recall brought of it."""

    first: int
    end: int
    deadline: float
    msgtype: str  # the topic's type, as its live batches came
    asked: bool = False
    resolved: bool = False
    batches: list[SampleBatch] = field(default_factory=list)


Store = Callable[[str, str, bytes, SampleBatch, int | None], None]
"""The recorder's store of one batch: topic, type, serialized bytes, message, log time [ns]."""


class GapRecall:
    """A respawned recorder's side: asks for what each channel's copy lacks before it goes on.

    While a channel's gap is asked for, every live sample batch (of every channel) is held,
    in arrival order; once every channel the copy holds has shown its gap (or the wait is
    over) and every gap is answered or given up, the recalled batches of all channels are
    stored first, interleaved by sample index, then the held ones. Storing one
    channel's whole gap before the other's would part the channels by the downtime in the
    bag, which a reader following the channels together takes for a skew past its bound.
    """

    def __init__(self, node: Node, store: Store, wait_s: float = RECALL_WAIT_S) -> None:
        self._node = node
        self._store = store
        self._wait_s = wait_s
        self._client = node.create_client(RecallSamples, RECALL_SERVICE)
        self._joins: dict[str, int] = {}  # topic -> the first index the copy lacks
        self._gaps: dict[str, _Gap] = {}
        self._held: list[tuple[str, str, bytes, SampleBatch]] = []
        self.ahead: dict[str, int] = {}
        """Per topic, the end of the live batches held: the recorder reports it taken (the
        sources go on) and never reports less while the held batches are stored."""

    def expect(self, topic: str, next_index: int) -> None:
        """The copy of topic ends before next_index: a later live batch shows the gap."""
        self._joins[topic] = next_index

    @property
    def waiting(self) -> dict[str, tuple[int, int]]:
        """The spans still asked for, by topic."""
        return {t: (gap.first, gap.end) for t, gap in self._gaps.items() if not gap.resolved}

    def take(self, topic: str, msgtype: str, data: bytes, msg: SampleBatch) -> bool:
        """True when a live batch is held here (a gap is being asked for)."""
        join = self._joins.pop(topic, None)
        if join is not None and msg.first_sample_index > join:
            deadline = time.monotonic() + self._wait_s
            self._gaps[topic] = _Gap(join, msg.first_sample_index, deadline, msgtype)
        if not self._gaps:
            return False
        self._held.append((topic, msgtype, data, msg))
        self.ahead[topic] = msg.first_sample_index + len(msg.samples)
        self.poll()
        return True

    def poll(self) -> None:
        """Ask once the service is there; give a gap up at its deadline (on the node's timer)."""
        for topic, gap in self._gaps.items():
            if gap.resolved:
                continue
            if not gap.asked and self._client.service_is_ready():
                gap.asked = True
                request = RecallSamples.Request(
                    topic=topic, first_sample_index=gap.first, end_sample_index=gap.end
                )
                self._client.call_async(request).add_done_callback(
                    lambda future, topic=topic, gap=gap: self._answered(topic, gap, future)
                )
            elif time.monotonic() > gap.deadline:
                self._give_up(
                    topic,
                    gap,
                    f'no answer on {RECALL_SERVICE} within {self._wait_s:g} s'
                    + ('' if gap.asked else ' (no node serves it: is the fitter running?)'),
                )
        self._release_if_done()

    def flush(self) -> None:
        """Store every held batch now (the recorder closes): the gaps not answered stay missing."""
        for topic, gap in self._gaps.items():
            if not gap.resolved:
                self._give_up(topic, gap, 'the recorder stopped before the recall was answered')
        self._release_if_done()

    def _answered(self, topic: str, gap: _Gap, future) -> None:
        if gap.resolved:
            return  # given up at its deadline
        error = future.exception()
        response = None if error is not None else future.result()
        if response is None or not response.success:
            self._give_up(
                topic, gap, f'{RECALL_SERVICE} failed: {error}' if error else response.message
            )
        else:
            batches = [
                batch
                for batch in response.batches
                if gap.first <= batch.first_sample_index
                and batch.first_sample_index + len(batch.samples) <= gap.end
            ]
            live = next(msg for held_topic, _, _, msg in self._held if held_topic == topic)
            if (
                batches
                and DEFAULT_RULES.same_clock(
                    msgs.stream_batch(batches[0]).origin_s, msgs.stream_batch(live).origin_s
                )
                is False
            ):
                self._give_up(topic, gap, 'the history held is of another acquisition')
            else:
                gap.batches, gap.resolved = batches, True
                recalled = sum(len(batch.samples) for batch in batches)
                self._node.get_logger().warning(
                    f'{topic}: samples {gap.first}..{gap.end} were sent while no recorder ran; '
                    f'{recalled} of them recalled from {RECALL_SERVICE} ({response.message})'
                )
        self._release_if_done()

    def _give_up(self, topic: str, gap: _Gap, why: str) -> None:
        gap.resolved = True
        self._node.get_logger().error(
            f'{topic}: samples {gap.first}..{gap.end} were sent while no recorder ran and are '
            f'not in the bag: {why}'
        )

    def _release_if_done(self) -> None:
        """Once every gap is resolved: the recalled batches by index, then the held ones.

        A channel the copy holds that has not shown its first live batch yet may still open
        a gap of its own: it is waited for until the first gap's deadline.
        """
        if not self._gaps or not all(gap.resolved for gap in self._gaps.values()):
            return
        if self._joins and time.monotonic() <= min(g.deadline for g in self._gaps.values()):
            return
        recalled = sorted(
            (
                (batch.first_sample_index, order, topic, gap.msgtype, batch)
                for order, (topic, gap) in enumerate(self._gaps.items())
                for batch in gap.batches
            ),
            key=lambda item: item[:2],
        )
        held, self._held, self._gaps = self._held, [], {}
        for _, _, topic, msgtype, batch in recalled:
            self._store(topic, msgtype, serialize_message(batch), batch, None)
        for topic, msgtype, data, msg in held:
            self._store(topic, msgtype, data, msg, None)
        self.ahead.clear()
