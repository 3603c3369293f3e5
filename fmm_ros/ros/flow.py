"""Flow control of the sample streams: sources wait for their consumers and never outrun them.

Sample batches travel RELIABLE: a batch published before its subscriber is matched is
lost. Measured on the multi-process rig at x50, when the queues were KEEP_LAST:
the velocity channel started at sample 532,500 and force had gaps of 43,500 samples, because
the sources published while the analyzer and the recorder were still starting, and faster
than they could take. The queues are KEEP_ALL now (`qos.SAMPLE_QOS`), so a reader behind a
burst keeps what it has not taken, but a writer then blocks only after 10,000 batches in
flight (`qos.SAMPLE_QUEUE_BATCHES`, reader and writer), up to 400 MB of 5,000-sample batches.

So the consumers say how far they have got (`ProgressReporter`, on fmm/stream_progress, one
message per node carrying each topic's next expected index) and the sources listen
(`FlowGate`):

- a source holds its first sample until every consumer it was told to wait for has reported
  and is matched on its topics; past `start_timeout_s` it stops, naming who is missing;
- it never publishes a batch ending more than `window` samples past the slowest consumer's
  index, so no queue ever holds more than the window (kept within half the QoS depth): above
  what the machine sustains the source slows down (its pacer re-anchors) instead of dropping;
- a consumer that leaves the graph (its node gone) stops counting; one that joins counts
  from its first report. A report from an earlier acquisition (past what the source has
  published since it restarted) counts as caught up.

A relay (rig_sim) reports on its input no further than its own consumers have got, so the
hold-back reaches the first source. The real DAQ cannot slow its hardware clock: it only
holds its start; its device buffer absorbs what its consumers lag.
"""

import math
import sys
import time
from collections.abc import Callable, Sequence

from rclpy.duration import Duration
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.publisher import Publisher

from fmm_interfaces.msg import StreamProgress
from fmm_ros.constants import STREAM_PROGRESS_TOPIC, resolve_name
from fmm_ros.errors import SourceStartTimeout
from fmm_ros.ros.health import OK, WARN
from fmm_ros.ros.params import Param
from fmm_ros.ros.qos import PROGRESS_LISTEN_QOS, PROGRESS_QOS, SAMPLE_QOS

# A consumer reports once it has taken REPORT_SIGNAL_S of signal since its last report
# (a sixteenth of the default window: the source never waits on the report's granularity),
# at most once in REPORT_MIN_PERIOD_S [s] (a report held back by that goes out when it is
# up), and what it took since goes out REPORT_TAIL_S later anyway (the end of a burst); both
# are one-shot timers, idle otherwise. Measured: the analyzer at real-time pace with a report
# per batch cost twice the CPU it costs without flow control.
REPORT_SIGNAL_S = 0.25
REPORT_MIN_PERIOD_S = 0.01
REPORT_TAIL_S = 0.1
# The flow-control topics are the package's own: no QoS event handlers in the wait sets
# (rclpy's executor rebuilds them every cycle, and they cost more than the messages).
QUIET_SUBSCRIPTION = SubscriptionEventCallbacks(use_default_callbacks=False)
# How often a source looks which consumers are still in the graph [s], and how long one may
# be missing from it before it stops counting [s] (discovery can blink). A consumer killed
# outright stays in the graph until its DDS lease runs out (20 s for Fast DDS): one that holds
# the source back and has not reported for SILENT_AFTER_S (counted from when it was sent what it
# lags on) stops counting too, until it reports.
GRAPH_CHECK_PERIOD_S = 1.0
LEFT_AFTER_S = 3.0
SILENT_AFTER_S = 5.0


# How far a source may fall behind its clock and still make the time up [s of wall time]:
# a stall shorter than this (a busy moment, a late report) costs no pace (`BatchPacer`);
# and the most batches one release step lets go meanwhile (2: twice the pace on ticks).
CATCH_UP_S = 1.0
CATCH_UP_BATCHES = 2

# How long a source waits, when it stops, for its last batches to be acknowledged [s].
LAST_BATCHES_TIMEOUT_S = 2.0


def deliver_last_batches(publishers: Sequence[Publisher]) -> None:
    """Wait until every matched subscriber has the batches published (a source stopping).

    A reliable writer may still hold the last batches when its process exits; without this
    the bag of a rig stopped in order lacked the source's last batch.
    """
    for publisher in publishers:
        publisher.wait_for_all_acked(Duration(seconds=LAST_BATCHES_TIMEOUT_S))


class ProgressReporter:
    """A consumer's side: reports, per SampleBatch topic it takes, the next index it expects."""

    def __init__(
        self,
        node: Node,
        topics: Sequence[str],
        *,
        announce: bool = True,
        max_skew_s: float = 0.0,
    ) -> None:
        """Report progress on topics (the resolved names of the node's subscriptions).

        announce=False: report only after `announce()` (a relay first waits for its own
        consumers). max_skew_s: how far its channels may part before it counts samples
        missing (its `StreamRules.max_skew_s`; 0 when it pairs none), which caps the
        sources' flow window (`PacedSource.window_now`).

        A node that pairs its channels (max_skew_s > 0) reports every channel it has begun
        at the slowest one's index. Each source then runs at most its window ahead of the
        pair, not of its own channel: hammer_sim's force reaches the fitter directly while
        the velocity comes through rig_sim, and per-channel reports let the force run two
        windows ahead of the velocity (hammer_sim's and rig_sim's). Measured on a loaded
        machine, rig started consumers first: the fitter declared 10,000 velocity samples
        missing past its 5 s skew and refused them when they came.
        """
        self._node = node
        self._name = node.get_fully_qualified_name()
        self._max_skew_s = float(max_skew_s)
        self._next = dict.fromkeys(topics, -1)
        self._reported: dict[str, int] = {}
        self._publisher = node.create_publisher(StreamProgress, STREAM_PROGRESS_TOPIC, PROGRESS_QOS)
        self._announced = False
        self._last_report = 0.0
        self._changed = False
        self._due = node.create_timer(REPORT_MIN_PERIOD_S, lambda: self._on_timer(self._due))
        self._tail = node.create_timer(REPORT_TAIL_S, lambda: self._on_timer(self._tail))
        self._due.cancel()
        self._tail.cancel()
        if announce:
            self.announce()

    @property
    def announced(self) -> bool:
        """Whether it has told the sources it consumes their topics."""
        return self._announced

    def announce(self) -> None:
        """Tell the sources this node consumes its topics (from here on it reports)."""
        self._announced = True
        self._report()

    def add(self, topic: str) -> None:
        """Report on one more topic (a resolved name) from now on."""
        self._next.setdefault(topic, -1)
        self._soon(now=True)

    def update(self, topic: str, next_index: int, sample_rate_hz: float | None = None) -> None:
        """The node has taken (or given up) every sample of topic below next_index.

        With the rate known, reported once REPORT_SIGNAL_S of signal went by (else soon).
        """
        if self._next.get(topic) == next_index:
            return
        self._next[topic] = int(next_index)
        moved = abs(next_index - self._reported.get(topic, -1))
        self._soon(now=not sample_rate_hz or moved >= REPORT_SIGNAL_S * sample_rate_hz)

    def _soon(self, now: bool) -> None:
        """Report now if due and REPORT_MIN_PERIOD_S has passed, else a little later."""
        self._changed = True
        if not now:
            if self._tail.is_canceled():
                self._tail.reset()
        elif time.monotonic() - self._last_report >= REPORT_MIN_PERIOD_S:
            self._report()
        elif self._due.is_canceled():
            self._due.reset()

    def _on_timer(self, timer) -> None:
        # A timer cancels only itself, here: one cancelled elsewhere while the executor had
        # it ready raises when the executor calls it ("timer is canceled").
        if self._changed:
            self._report()
        else:
            timer.cancel()

    def _report(self) -> None:
        if not self._announced:
            return
        message = StreamProgress()
        message.node = self._name
        message.topics = list(self._next)
        message.next_sample_indices = self._reported_indices()
        message.max_skew_s = self._max_skew_s
        self._publisher.publish(message)
        self._reported = dict(self._next)
        self._last_report = time.monotonic()
        self._changed = False

    def _reported_indices(self) -> list[int]:
        """Each topic's next index as reported: the slowest begun one's, when channels pair."""
        indices = list(self._next.values())
        begun = [index for index in indices if index >= 0]
        if self._max_skew_s <= 0 or not begun:
            return indices
        slowest = min(begun)
        return [slowest if index >= 0 else index for index in indices]


class FlowGate:
    """A source's side: when its first sample may go, and whether the next may go now."""

    def __init__(
        self,
        node: Node,
        publishers: Sequence[Publisher],
        *,
        wait_for: Sequence[str],
        start_timeout_s: float,
        on_progress: Callable[[], None] | None = None,
        silent_after_s: float = SILENT_AFTER_S,
    ) -> None:
        """Gate the source's SampleBatch publishers.

        wait_for: node names (relative to the source's namespace, or absolute) that must
        report before the first sample; a start_timeout_s of 0 waits for ever.
        silent_after_s: how long a consumer that lags may say nothing before it stops
        counting (`lag`), an awaited one also past its DDS lease (`_forget_departed`).
        """
        self._node = node
        self._silent_after_s = float(silent_after_s)
        self._publishers = {publisher.topic_name: publisher for publisher in publishers}
        namespace = node.get_namespace()
        self.wait_for = [resolve_name(name, namespace) for name in wait_for if name]
        self._timeout_s = start_timeout_s
        self._created = time.monotonic()
        # node -> topic -> next index it expects; when a node was last seen in the graph.
        self._progress: dict[str, dict[str, int]] = {}
        self._seen: dict[str, float] = {}
        self._heard: dict[str, float] = {}  # when each last reported
        # When each consumer, caught up, was last sent samples: its silence counts from the
        # later of that and its last report, not from a report made while it had nothing.
        self._owed_since: dict[str, float] = {}
        self._skews: dict[str, float] = {}  # each consumer's max_skew_s (0: none)
        self._silent: dict[str, bool] = {}  # consumers not waited for while silent
        # Consumers (re)started after the source started (a respawned node reporting less
        # than before, a late plot reporting nothing): the index the source had reached
        # then, from which they count.
        self._joined_at: dict[str, int] = {}
        self._highest: dict[str, dict[str, int]] = {}  # each node's highest report this acquisition
        self._graph_checked = 0.0
        self.first_index = 0  # where the source's current acquisition began
        self.published_end = 0  # index after the last sample published
        self.started = False
        self.holding_for = ''  # the slowest consumer while the window is full ('' otherwise)
        self._on_progress_hook = on_progress
        node.create_subscription(
            StreamProgress,
            STREAM_PROGRESS_TOPIC,
            self._on_progress,
            PROGRESS_LISTEN_QOS,
            event_callbacks=QUIET_SUBSCRIPTION,
        )

    def _on_progress(self, message: StreamProgress) -> None:
        mine = {
            topic: index
            for topic, index in zip(message.topics, message.next_sample_indices, strict=False)
            if topic in self._publishers
        }
        if mine:
            before = self._highest.setdefault(message.node, {})
            late = not before and all(index < self.first_index for index in mine.values())
            back = any(index < before.get(topic, -1) for topic, index in mine.items())
            if self.started and (late or back):
                # A node (re)started under this name (a respawn, a late plot): it is sent
                # nothing older than now (VOLATILE), whatever it reports (nothing, or where
                # a killed recorder's bag ended), so it counts from here.
                self._joined_at[message.node] = self.published_end
                before.clear()  # what it reports from now on is the new node's
            for topic, index in mine.items():
                if index <= self.published_end:  # not an earlier, longer acquisition's
                    before[topic] = max(index, before.get(topic, -1))
            self._progress[message.node] = mine
            self._skews[message.node] = message.max_skew_s
            self._seen[message.node] = self._heard[message.node] = time.monotonic()
            if self._silent.pop(message.node, None):
                self._node.get_logger().warning(
                    f'consumer {message.node} reports again, at '
                    + ', '.join(f'{topic} {index}' for topic, index in mine.items())
                    + f' (published up to {self.published_end})'
                )
            if self._on_progress_hook:
                self._on_progress_hook()

    # -- the start ---------------------------------------------------------------------------

    def ready(self) -> bool:
        """True once every awaited consumer has reported and is matched on its topics.

        Raises SourceStartTimeout, naming who is missing, after the start timeout.
        """
        if self.started:
            return True
        missing = [name for name in self.wait_for if name not in self._progress]
        unmatched = {
            topic: (publisher.get_subscription_count(), self._consumers(topic))
            for topic, publisher in self._publishers.items()
            if publisher.get_subscription_count() < len(self._consumers(topic))
        }
        if not missing and not unmatched:
            self.started = True
            return True
        if self._timeout_s and time.monotonic() - self._created > self._timeout_s:
            raise SourceStartTimeout(self.describe_wait(missing, unmatched))
        return False

    def describe_wait(self, missing=None, unmatched=None) -> str:
        """Who the source is waiting for, and who has reported."""
        if missing is None:
            missing = [name for name in self.wait_for if name not in self._progress]
        present = ', '.join(sorted(self._progress)) or 'none'
        text = (
            f'{len(missing)} of {len(self.wait_for)} consumers missing after '
            f'{time.monotonic() - self._created:.0f} s: {", ".join(missing) or "none"} '
            f'(reported: {present}; topics {", ".join(self._publishers)})'
        )
        for topic, (matched, consumers) in (unmatched or {}).items():
            text += f'; {topic} matched {matched} of {len(consumers)} subscribers'
        return text

    @property
    def publishers(self) -> list[Publisher]:
        """The source's SampleBatch publishers."""
        return list(self._publishers.values())

    @property
    def consumers(self) -> list[str]:
        """The nodes that have reported on the source's topics."""
        return sorted(self._progress)

    def _consumers(self, topic: str) -> list[str]:
        return [name for name, topics in self._progress.items() if topic in topics]

    # -- the pace ----------------------------------------------------------------------------

    def begin(self, first_index: int) -> None:
        """The source (re)starts its acquisition at first_index.

        The consumers it knows stay known, at nothing taken yet: forgotten, the next report
        of one that has taken nothing (-1) read as a node started late, counted from where
        the source was. rig_sim begins on its first force batch, after its consumers
        reported, and so counted the fitter's velocity caught up while the fitter had not
        taken any: the hammer ran on and the fitter declared 22,000 velocity samples missing.
        """
        self.first_index = self.published_end = int(first_index)
        self._joined_at.clear()
        self._highest = {name: dict.fromkeys(topics, -1) for name, topics in self._progress.items()}

    def sent(self, end_index: int) -> None:
        """The source published samples up to end_index (exclusive).

        A consumer that had taken everything before owes these samples from now: one that
        reported long ago because nothing came (started before the source, or the source
        idle) is not silent the moment the source goes on. Counted from its last report,
        every consumer started silent_after_s before the hammer would be left out at its first
        batch (the any-order rig test starts them 4 s early), and nothing would hold the force
        back from running past a consumer's max_skew_s ahead of the velocity.
        """
        end_index = int(end_index)
        if end_index > self.published_end:
            now = time.monotonic()
            for name in self._progress:
                if self._behind(name) == 0:
                    self._owed_since[name] = now
        self.published_end = max(self.published_end, end_index)

    def _behind(self, name: str, topic: str | None = None) -> int | None:
        """Samples consumer name is behind on topic (or its slowest); None: not its topic."""
        return max(
            (
                self.published_end - self._effective(index, self._joined_at.get(name))
                for candidate, index in self._progress[name].items()
                if topic is None or candidate == topic
            ),
            default=None,
        )

    def lag(self, topic: str | None = None) -> dict[str, int]:
        """Samples each consumer (of topic, or any) is behind what was published.

        A consumer that lags and has been silent for SILENT_AFTER_S since it was sent what it
        lags on is left out (logged once).
        """
        self._forget_departed()
        now = time.monotonic()
        lags = {}
        for name in self._progress:
            behind = self._behind(name, topic)
            if behind is None:
                continue
            since = max(self._heard.get(name, now), self._owed_since.get(name, 0.0))
            if behind > 0 and now - since > self._silent_after_s:
                if not self._silent.get(name):
                    self._silent[name] = True
                    self._node.get_logger().warning(
                        f'consumer {name} has said nothing for {self._silent_after_s:g} s with '
                        f'{behind} samples outstanding (from sample '
                        f'{self.published_end - behind} on, while the others go on): no '
                        'longer waited for; what it misses its own ledger names'
                    )
                continue
            lags[name] = behind
        return lags

    def allows(self, end_index: int, window: int) -> bool:
        """Whether a batch ending at end_index keeps every consumer within window samples."""
        lags = self.lag()
        slowest = max(lags, key=lags.get, default='')
        behind = lags.get(slowest, 0) + end_index - self.published_end
        self.holding_for = slowest if behind > window else ''
        return not self.holding_for

    def tightest_skew(self) -> tuple[float, str]:
        """The smallest max_skew_s a consumer counting now reported [s], and its name.

        (inf, '') when none pairs channels.
        """
        limits = [
            (self._skews.get(name, 0.0), name)
            for name in self._progress
            if self._skews.get(name, 0.0) > 0.0 and not self._silent.get(name)
        ]
        return min(limits, default=(math.inf, ''))

    def slowest_index(self, topic: str) -> int:
        """The lowest index the consumers of topic expect (published_end without any)."""
        lags = self.lag(topic)
        return self.published_end - max(lags.values(), default=0)

    def _effective(self, index: int, joined_at: int | None = None) -> int:
        """A reported index as progress in the current acquisition.

        joined_at: where a consumer (re)started after the start counts from until it
        reports more (it is sent nothing older: VOLATILE), so a respawned consumer never
        holds the source for what it could not receive.
        """
        if joined_at is not None and index < joined_at:
            return min(joined_at, self.published_end)
        if index < self.first_index:
            return self.first_index  # nothing yet (-1), or an earlier acquisition's
        return min(index, self.published_end)  # beyond: an earlier, longer acquisition's

    def _forget_departed(self) -> None:
        """Consumers whose node has left the graph stop counting."""
        now = time.monotonic()
        if now - self._graph_checked < GRAPH_CHECK_PERIOD_S:
            return
        self._graph_checked = now
        present = set()
        for topic in self._publishers:
            for info in self._node.get_subscriptions_info_by_topic(topic):
                present.add(resolve_name(info.node_name, info.node_namespace))
        for name in list(self._progress):
            if name in present:
                self._seen[name] = now
            elif now - self._seen.get(name, now) > LEFT_AFTER_S and (
                name not in self.wait_for or now - self._heard.get(name, now) > self._silent_after_s
            ):  # an awaited one is waited for silent_after_s (its respawn), not the DDS lease
                del self._progress[name]
                self._joined_at.pop(name, None)
                self._owed_since.pop(name, None)
                self._highest.pop(name, None)
                self._node.get_logger().warning(
                    f'consumer {name} left the graph: no longer waited for'
                )


# Every source's flow-control parameters (hammer_sim, daq, player).
SOURCE_PARAMS = (
    Param(
        'wait_for_consumers',
        [''],
        'Nodes (names in this namespace, or absolute) that must report on fmm/stream_progress '
        'before the first sample goes out: a batch sent before they are matched is lost; '
        '[""] for none',
        read_only=True,
    ),
    Param(
        'start_timeout_s',
        60.0,
        'How long to wait for them before stopping with their names [s]; 0 waits for ever',
        limits=(0.0, 86_400.0),
        read_only=True,
    ),
    Param(
        'silent_after_s',
        SILENT_AFTER_S,
        'How long a consumer that lags may say nothing before the source goes on without it '
        "[s] (a stall, or a node killed: DDS keeps a killed node's name 20 s); longer holds the "
        'source while a node respawns, which then loses only what was in flight to it',
        limits=(0.1, 3600.0),
        read_only=True,
    ),
    Param(
        'flow_window_s',
        4.0,
        'Signal a consumer may lag behind before the source holds back [s] (also capped at '
        'half the sample QoS depth in batches, and a batch under the smallest max_skew_s a '
        'consumer reports)',
        limits=(0.01, 600.0),
        read_only=True,
    ),
)

# The sources that make their own batches (hammer_sim, the daq's file source): how many
# messages a second a topic may carry before batches grow with the pace, and how many paced
# batches at least fit the flow window (two left one batch in flight once the window is held
# under max_skew_s). Profiled at x50: publish() of 5,000-sample batches was 30 % of
# hammer_sim's CPU and 25 % of rig_sim's: at 50 (10,000 samples at x50) the graph kept x49.6
# asked x50 where 100 kept x34.2 (back to back, idle cores). The larger batches reach a viewer
# as bursts of display points, which DISPLAY_QOS's deeper queue holds.
WINDOW_BATCHES = 4
MAX_BATCHES_PARAM = Param(
    'max_batches_per_s',
    50.0,
    'Messages a second per topic at most [1/s]: at a faster pace a message carries a whole '
    'multiple of batch_size (rclpy costs per message; within the flow window); 0: always '
    'batch_size',
    limits=(0.0, 100_000.0),
    read_only=True,
)


class PacedSource:
    """A source's release of batches: held for its consumers, then paced, within the window.

    The start waits for the consumers (FlowGate.ready); then the wall-clock pace (BatchPacer),
    never past the flow window of the slowest consumer.
    """

    def __init__(
        self,
        node: Node,
        publishers: Sequence[Publisher],
        config: dict,
        *,
        batches_per_s: float,
        window_samples: int,
        pace_label: str,
        release: Callable[[], None] | None = None,
        sample_rate_hz: float = 0.0,
    ) -> None:
        """Pace a source's publishers under its config (SOURCE_PARAMS values).

        release: the source's own release step (its timer callback), also run when a report
        arrives while the window held it back, so it need not wait for its next tick.
        sample_rate_hz: its rate, to hold the window under the consumers' max_skew_s
        (`window_now`); 0 for a source that paces by other means (the player).
        """
        self._node = node
        self._release = release
        self.gate = FlowGate(
            node,
            publishers,
            wait_for=config['wait_for_consumers'],
            start_timeout_s=config['start_timeout_s'],
            on_progress=self._on_progress,
            silent_after_s=config.get('silent_after_s', SILENT_AFTER_S),
        )
        self.pacer = BatchPacer(batches_per_s)
        self.window = int(window_samples)
        self.sample_rate_hz = float(sample_rate_hz)
        self.label = pace_label
        self._skew_logged: tuple[float, str] = (math.inf, '')
        self._waiting_logged = 0.0
        self._began = time.monotonic()
        self._published_at_start = 0

    def _on_progress(self) -> None:
        if self._release is not None and self.gate.holding_for:
            self._release()

    @staticmethod
    def window_samples(config: dict, sample_rate_hz: float, batch_size: int) -> int:
        """The flow window [samples]: flow_window_s of signal, within bounds.

        At most half the QoS depth in batches, at least two batches (one in flight while the
        next is taken).
        """
        by_time = int(config['flow_window_s'] * sample_rate_hz)
        return max(2 * batch_size, min(by_time, SAMPLE_QOS.depth // 2 * batch_size))

    @staticmethod
    def paced_batch(
        config: dict, sample_rate_hz: float, batch_size: int, rate_factor: float
    ) -> int:
        """Samples a message at `rate_factor` times real time (`MAX_BATCHES_PARAM`).

        A whole multiple of batch_size, so that at most max_batches_per_s messages a second go
        out on a topic (at x50 in 500-sample batches the five-node graph spent its cores on
        rclpy's per-message cost), and WINDOW_BATCHES still fit flow_window_s of signal
        (fewer in flight and the source waits for each report).
        """
        cap = config['max_batches_per_s']
        if cap <= 0:
            return batch_size
        multiple = math.ceil(sample_rate_hz * rate_factor / batch_size / cap)
        window = int(config['flow_window_s'] * sample_rate_hz)
        most = max(1, window // (WINDOW_BATCHES * batch_size))
        return batch_size * min(max(1, multiple), most)

    def ready(self) -> bool:
        """Whether the first sample may go (logs whom it waits for every 5 s)."""
        if self.gate.started:
            return True
        if self.gate.ready():
            self.pacer.restart(self.pacer.batches_per_s, self.pacer.released)
            self._began = time.monotonic()
            self._published_at_start = self.gate.published_end
            self._node.get_logger().info(
                f'consumers ready ({", ".join(self.gate.consumers) or "none awaited"}): starting'
            )
            return True
        if time.monotonic() - self._waiting_logged > 5.0:
            self._waiting_logged = time.monotonic()
            self._node.get_logger().info(f'holding the first sample: {self.gate.describe_wait()}')
        return False

    def window_now(
        self, batch_samples: int, window: int | None = None, sample_rate_hz: float | None = None
    ) -> int:
        """The flow window [samples], held a batch under every consumer's max_skew_s.

        A source runs at most the window ahead of the slowest consumer of any of its
        channels, which is as far as one channel can run ahead of another in a consumer:
        past that consumer's max_skew_s it counts the lagging channel's samples missing.
        Measured: hammer_sim at x50 with flow_window_s 8 cost the fitter, whose
        max_skew_s is 5, 180,000 velocity samples declared missing and 36 batches refused.
        window, sample_rate_hz: a batch's own (the player's batches carry theirs); by default
        the source's.
        """
        window = self.window if window is None else window
        rate = self.sample_rate_hz if sample_rate_hz is None else sample_rate_hz
        skew_s, name = self.gate.tightest_skew()
        if not rate or not math.isfinite(skew_s):
            return window
        cap = max(batch_samples, int(skew_s * rate) - batch_samples)
        if cap < window and (skew_s, name) != self._skew_logged:
            self._skew_logged = (skew_s, name)
            self._node.get_logger().warning(
                f'flow window held to {cap / rate:g} s of signal, under the '
                f'max_skew_s {skew_s:g} s of {name} (flow_window_s asks {window / rate:g} s)'
            )
        return min(window, cap)

    def due(self, batch_samples: int) -> int:
        """How many batches of batch_samples may go now (clock and flow window)."""
        count = 0
        window = self.window_now(batch_samples)
        # What a stall owes goes at once where consumers report (their window bounds it).
        most = sys.maxsize if self.gate.consumers else CATCH_UP_BATCHES
        for _ in range(self.pacer.due(most)):
            end = self.gate.published_end + (count + 1) * batch_samples
            if not self.gate.allows(end, window):
                break
            count += 1
        if self.pacer.fell_behind:
            reason = (
                f'{self.gate.holding_for} lags by more than the flow window'
                if self.gate.holding_for
                else 'the graph is slower'
            )
            self._node.get_logger().warning(
                f'cannot keep {self.label}: running slower ({reason})',
                throttle_duration_sec=10.0,
            )
        return count

    def sent(self, end_index: int) -> None:
        """One batch, ending at end_index, went out."""
        self.pacer.release()
        self.gate.sent(end_index)

    def finish(self) -> None:
        """The source stops: its last batches reach every matched consumer first."""
        deliver_last_batches(self.gate.publishers)

    def status(self, sample_rate_hz: float, asked: float) -> tuple:
        """The source part of /diagnostics: pace achieved against asked, consumer lags."""
        if not self.gate.started:
            return WARN, f'holding the first sample: {self.gate.describe_wait()}', {}
        wall = max(time.monotonic() - self._began, 1e-9)
        signal_s = (self.gate.published_end - self._published_at_start) / sample_rate_hz
        pace = signal_s / wall
        lags = {name: lag / sample_rate_hz for name, lag in self.gate.lag().items()}
        values = {
            'published up to sample': self.gate.published_end,
            'pace achieved x': pace,
            'pace asked x': asked,
            'holding for': self.gate.holding_for or 'nobody',
            **{f'lag of {name} s': lag for name, lag in sorted(lags.items())},
        }
        slow = pace < 0.9 * asked and wall > 5.0
        level = WARN if slow else OK
        message = f'x{pace:.3g} of x{asked:g} asked' + (
            f', held back by {self.gate.holding_for}' if self.gate.holding_for else ''
        )
        return level, message, values


class BatchPacer:
    """Releases sample batches at a paced rate against the wall clock, making up short stalls.

    A source that falls behind its clock by at most `catch_up_s` (the machine busy for a
    moment, a consumer's report late) makes the time up: a call lets up to `most` go (all
    that is owed where a flow window bounds it, `PacedSource.due`; CATCH_UP_BATCHES, twice
    the asked pace on ticks, where none does: all at once could flood a subscriber nothing
    guards). Further behind (the graph is slower than asked), the clock is re-anchored: the
    source runs slower than asked (`fell_behind` says so) instead of flooding. Measured:
    re-anchoring once two batches behind lost every stall longer than 20 ms for
    good at x50, which gave x44.9 of x50 on a graph that sustained x77.5 when asked x100.
    """

    def __init__(self, batches_per_s: float, catch_up_s: float = CATCH_UP_S) -> None:
        self.catch_up_s = catch_up_s
        self.fell_behind = False
        self.restart(batches_per_s, 0)

    def restart(self, batches_per_s: float, released: int) -> None:
        """Pace at a new rate from the next tick on, `released` batches already out."""
        self._anchor = (None, released, batches_per_s)
        self.batches_per_s = batches_per_s
        self.released = released

    def due(self, most: int = CATCH_UP_BATCHES) -> int:
        """How many batches the clock lets go now (at most `most`), each counted by `release()`.

        The first call after (re)starting anchors the pace, so the time a graph spends on
        discovery before it spins is not counted as lag.
        """
        wall0, released0, rate = self._anchor
        now = time.monotonic()
        if wall0 is None:
            self._anchor = (wall0 := now, released0, rate)
        behind = released0 + int((now - wall0) * rate) - self.released
        self.fell_behind = behind > max(2, int(self.catch_up_s * rate))
        if self.fell_behind:
            self._anchor = (now, self.released + 1, rate)
            return 1
        return max(0, min(behind, most))

    def release(self) -> None:
        """One batch went out."""
        self.released += 1
