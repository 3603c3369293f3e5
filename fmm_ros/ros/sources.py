"""Who feeds a consumer's sample topics: two sources on one topic, or channels at two rates.

Both break the stream in ways its rules can only see as symptoms: a second
hammer_sim on the same namespace made 2,007 resynchronisations and rejected hits `gap,
interrupted`; velocity at 5 kHz beside force at 10 kHz had every force batch refused as
another acquisition's. `SourceCheck` names the cause instead: each second (on /diagnostics)
it counts the publishers of each sample topic in the graph, and it compares the rates the
channels' batches state. Either fault is ERROR on /diagnostics (part `sources`) and one log
line when it begins (another when it ends), naming the topics, publishers and rates.
"""

from rclpy.node import Node

from fmm_ros.ros.health import ERROR, OK


class SourceCheck:
    """Counts the publishers of a consumer's sample topics; compares the channels' rates."""

    def __init__(self, node: Node, topics: dict[str, str]) -> None:
        """topics: channel (quantity) -> resolved topic name."""
        self._node = node
        self._topics = dict(topics)
        self._rates: dict[str, float] = {}
        self._reported = ''

    def saw(self, quantity: str, sample_rate_hz: float) -> None:
        """A batch of a channel arrived stating this rate."""
        self._rates[quantity] = sample_rate_hz

    def problems(self) -> list[str]:
        """What is wrong with the sources now, one phrase each (empty: nothing)."""
        found = []
        for topic in self._topics.values():
            publishers = self._node.get_publishers_info_by_topic(topic)
            if len(publishers) > 1:
                names = ', '.join(
                    sorted(
                        f'{info.node_namespace.rstrip("/")}/{info.node_name}' for info in publishers
                    )
                )
                found.append(f'{len(publishers)} sources on {topic} ({names})')
        if len(set(self._rates.values())) > 1:
            rates = ', '.join(f'{quantity} {rate:g} Hz' for quantity, rate in self._rates.items())
            found.append(f'channels at different sample rates ({rates})')
        return found

    def status(self) -> tuple:
        """The `sources` part of /diagnostics; logs a change of what is wrong once."""
        problems = self.problems()
        text = '; '.join(problems)
        if text != self._reported:
            if text:
                self._node.get_logger().error(f'{text}: the stream cannot follow one acquisition')
            else:
                self._node.get_logger().info('sources: one per topic, one rate again')
            self._reported = text
        if problems:
            return ERROR, text, {'problems': text}
        return OK, 'one source per topic, one sample rate', {}
