"""Who feeds a consumer's sample topics: two sources on one topic, or channels at two rates.

Both break the stream in ways its rules can only see as symptoms: a second
hammer_sim on the same namespace made 2,007 resynchronisations and rejected hits `gap,
interrupted`; velocity at 5 kHz beside force at 10 kHz had every force batch refused as
another acquisition's. `SourceCheck` names the cause instead: it counts the publishers of
each sample topic in the graph, and it compares the rates the channels' batches state.
Either fault is ERROR on /diagnostics (part `sources`) and one log line when it begins
(another when it ends), naming the topics, publishers (`two sources publish /fmm/force:
/a/hammer_sim, /b/hammer_sim`, a publisher's GID where its node is not known yet) and
rates, whatever the batches' frame_ids. It checks each second with /diagnostics and, while
a topic's subscription says more than one publisher is matched (its matched event), at each
batch, with /diagnostics published at once on a change: named within one batch.
"""

from collections.abc import Callable

from rclpy.node import Node

from fmm_ros.ros.health import ERROR, OK

COUNT_WORDS = {2: 'two', 3: 'three', 4: 'four'}
UNKNOWN_NODE = '_NODE_NAME_UNKNOWN_'  # what the graph says before a node's name is discovered


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

    def matched(self, quantity: str, current_count: int) -> None:
        """The subscription of a channel now matches this many publishers (matched event)."""
        self._matched[quantity] = current_count
        if current_count > 1:
            self.check()

    def saw(self, quantity: str, sample_rate_hz: float) -> None:
        """A batch of a channel arrived stating this rate: checked now if anything is off."""
        changed = self._rates.get(quantity) != sample_rate_hz
        self._rates[quantity] = sample_rate_hz
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

    def status(self) -> tuple:
        """The `sources` part of /diagnostics."""
        problems = self.check(notify=False)  # /diagnostics is being published already
        if problems:
            text = '; '.join(problems)
            return ERROR, text, {'problems': text}
        return OK, 'one source per topic, one sample rate', {}
