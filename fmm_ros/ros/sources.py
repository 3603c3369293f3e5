"""Who feeds a consumer's sample topics: two sources, two rates, or a source not held back.

Two sources on one topic and channels at two rates both break the stream in ways its rules can
only see as symptoms: a second hammer_sim on the same namespace made 2,007 resynchronisations
and rejected hits `gap, interrupted`; velocity at 5 kHz beside force at 10 kHz had every force
batch refused as another acquisition's. `SourceCheck` names the cause instead: it counts the
publishers of each sample topic in the graph, and it compares the rates the channels' batches
state. Either fault is ERROR on /diagnostics (part `sources`) and one log line when it begins
(another when it ends), naming the topics, publishers (`two sources publish /fmm/force:
/a/hammer_sim, /b/hammer_sim`, a publisher's GID where its node is not known yet) and rates,
whatever the batches' frame_ids. It checks each second with /diagnostics and, while a topic's
subscription says more than one publisher is matched (its matched event), at each batch, with
/diagnostics published at once on a change: named within one batch.

A publisher of a sample topic whose node does not listen to fmm/stream_progress (a lab's DAQ
driver, `ros2 bag play`) is one the flow control cannot hold back. The graph cannot tell a
KEEP_ALL writer (held back by the middleware once the reader's queue is full) from a KEEP_LAST
one (it overwrites what it has not delivered): the history a writer offers is not in DDS
discovery (rclpy reports it UNKNOWN). So each such publisher is named when it is matched (while
its node is not discovered yet, at the first batch after that), long before a KEEP_LAST writer
of depth d can lose anything (d batches behind), WARN on /diagnostics (part `sources`, key
`unpaced publishers`) and one log line, with the contract it falls under
(docs/explanation/reliability.md): what a KEEP_LAST writer sends faster than this node takes
is lost, and counted after the fact (parts `transport` and `stream`). A best-effort publisher
is ERROR: this node's reliable subscriptions do not match it, so none of its batches arrive.
"""

from collections.abc import Callable

from rclpy.node import Node
from rclpy.qos import ReliabilityPolicy

from fmm_ros.constants import STREAM_PROGRESS_TOPIC, resolve_name
from fmm_ros.ros.health import ERROR, OK, WARN
from fmm_ros.ros.qos import SAMPLE_QUEUE_BATCHES

COUNT_WORDS = {2: 'two', 3: 'three', 4: 'four'}
UNKNOWN_NODE = '_NODE_NAME_UNKNOWN_'  # what the graph says before a node's name is discovered
UNPACED_CONTRACT = (
    'a KEEP_ALL writer is held back once this node holds '
    f'{SAMPLE_QUEUE_BATCHES:,} batches of a topic; a KEEP_LAST writer loses what it sends '
    'faster than this node takes, counted after the fact (transport, stream)'
)
"""What this node promises a source it cannot slow down (docs/explanation/reliability.md)."""


def publisher_name(info: object) -> str:
    """A publisher as the graph knows it: its node's full name, or its GID."""
    if info.node_name and info.node_name != UNKNOWN_NODE:
        return f'{info.node_namespace.rstrip("/")}/{info.node_name}'
    return 'gid ' + bytes(info.endpoint_gid).hex()


class SourceCheck:
    """Counts the publishers of a consumer's sample topics; compares the channels' rates."""

    def __init__(
        self, node: Node, topics: dict[str, str], on_change: Callable[[], None] | None = None
    ) -> None:
        """Check the topics (channel (quantity) -> resolved topic name).

        on_change: called when what is wrong changes (publish /diagnostics now).
        """
        self._node = node
        self._topics = dict(topics)
        self._rates: dict[str, float] = {}
        self._matched: dict[str, int] = {}
        self._reported = ''
        self._on_change = on_change
        self._progress_topic = resolve_name(STREAM_PROGRESS_TOPIC, node.get_namespace())
        self._unpaced: dict[str, list[str]] = {}  # topic -> publishers not held back
        self._best_effort: dict[str, list[str]] = {}  # topic -> best-effort publishers
        self._unknown = False  # a publisher whose node is not discovered yet: look again
        self._paced_reported = ''

    def matched(self, quantity: str, current_count: int) -> None:
        """The subscription of a channel now matches this many publishers (matched event)."""
        self._matched[quantity] = current_count
        self.check_pacing()
        if current_count > 1:
            self.check()

    def saw(self, quantity: str, sample_rate_hz: float) -> None:
        """A batch of a channel arrived stating this rate: checked now if anything is off."""
        changed = self._rates.get(quantity) != sample_rate_hz
        self._rates[quantity] = sample_rate_hz
        if self._unknown:  # until every publisher's node is known: a graph query a batch
            self.check_pacing()
        if changed or self._reported or any(n > 1 for n in self._matched.values()):
            self.check()

    def problems(self) -> list[str]:
        """What is wrong with the sources now, one phrase each (empty: nothing)."""
        found = []
        for topic in self._topics.values():
            publishers = self._node.get_publishers_info_by_topic(topic)
            if len(publishers) > 1:
                names = ', '.join(sorted(publisher_name(info) for info in publishers))
                count = COUNT_WORDS.get(len(publishers), str(len(publishers)))
                found.append(f'{count} sources publish {topic}: {names}')
        if len(set(self._rates.values())) > 1:
            rates = ', '.join(f'{quantity} {rate:g} Hz' for quantity, rate in self._rates.items())
            found.append(f'channels at different sample rates ({rates})')
        return found

    def check(self, notify: bool = True) -> list[str]:
        """Look now; log a change of what is wrong once (and call on_change if notify)."""
        problems = self.problems()
        text = '; '.join(problems)
        if text != self._reported:
            if text:
                self._node.get_logger().error(f'{text}: the stream cannot follow one acquisition')
            else:
                self._node.get_logger().info('sources: one per topic, one rate again')
            self._reported = text
            if notify and self._on_change is not None:
                self._on_change()
        return problems

    def check_pacing(self, notify: bool = True) -> None:
        """Find the publishers the flow control cannot hold back; log a change once."""
        listening = {
            (info.node_namespace.rstrip('/'), info.node_name)
            for info in self._node.get_subscriptions_info_by_topic(self._progress_topic)
        }
        self._unknown = False
        self._unpaced, self._best_effort = {}, {}
        for topic in self._topics.values():
            for info in self._node.get_publishers_info_by_topic(topic):
                name = publisher_name(info)
                if info.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT:
                    self._best_effort.setdefault(topic, []).append(name)
                elif not info.node_name or info.node_name == UNKNOWN_NODE:
                    self._unknown = True  # cannot tell yet whether it listens
                elif (info.node_namespace.rstrip('/'), info.node_name) not in listening:
                    self._unpaced.setdefault(topic, []).append(name)
        text = self._pacing_text()
        if text != self._paced_reported:
            if self._best_effort:
                self._node.get_logger().error(text)
            elif text:
                self._node.get_logger().warning(text)
            self._paced_reported = text
            if notify and self._on_change is not None:
                self._on_change()

    def _pacing_text(self) -> str:
        best_effort = '; '.join(
            f'{", ".join(sorted(names))} publishes {topic} best-effort: this node subscribes '
            'reliably and does not match it, none of its batches arrive'
            for topic, names in sorted(self._best_effort.items())
        )
        unpaced = '; '.join(
            f'{", ".join(sorted(names))} publishes {topic} without flow control'
            for topic, names in sorted(self._unpaced.items())
        )
        if unpaced:
            unpaced += f' ({self._progress_topic} not heard): {UNPACED_CONTRACT}'
        return '; '.join(text for text in (best_effort, unpaced) if text)

    def status(self) -> tuple:
        """The `sources` part of /diagnostics."""
        problems = self.check(notify=False)  # /diagnostics is being published already
        self.check_pacing(notify=False)
        values = {
            'unpaced publishers': ', '.join(
                sorted({name for names in self._unpaced.values() for name in names})
            )
        }
        pacing = self._pacing_text()
        if problems or self._best_effort:
            text = '; '.join([*problems, pacing] if pacing else problems)
            return ERROR, text, {'problems': text, **values}
        if self._unpaced:
            return WARN, pacing, values
        return OK, 'one source per topic, one sample rate, every source held back', values
