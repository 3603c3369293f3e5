"""player: republishes a recorded bag into the live graph, paced by its log times.

The stored CDR bytes are published as they are (no decode), at `rate_factor` times the pace
they were recorded at, so the analyzer and the fitter see the session again exactly as
recorded: same sample indices, same batches. A recorded fmm topic is published under its
relative name (a bag of /rig2/fmm/force plays on fmm/force in the player's namespace); other
topics keep their recorded names. Like every source it holds its first batch for the
consumers in `wait_for_consumers` and never runs more than the flow window ahead of the
slowest (ros/flow.py). For analysis without a ROS graph, `fmm replay` feeds a bag straight
into the core instead.
"""

import time

from rclpy.node import Node

from fmm_ros.constants import (
    APPLIED_FORCE_TOPIC,
    CLOCK_TOPIC,
    FORCE_TOPIC,
    FRF_TOPIC,
    IMPACTS_TOPIC,
    VELOCITY_TOPIC,
)
from fmm_ros.errors import BadInputError
from fmm_ros.io.bags.definitions import SAMPLE_BATCH
from fmm_ros.io.bags.reader import BagReader
from fmm_ros.ros.common import message_class, run_node, shared_params
from fmm_ros.ros.flow import CATCH_UP_S, SOURCE_PARAMS, PacedSource
from fmm_ros.ros.health import OK, WARN, Health
from fmm_ros.ros.nodes.recorder import KNOWN_TOPICS
from fmm_ros.ros.params import Param, declare_parameters
from fmm_ros.ros.qos import RESULT_QOS, SAMPLE_QOS
from fmm_ros.ros.timebase import CLOCK_PARAM, ClockPublisher

# As for hammer_sim (flow.BatchPacer): rclpy takes one message per subscription per wait
# cycle, so a tick sends a few messages at most, and a stall is made up over later ticks.
MAX_MESSAGES_PER_TICK = 4

PARAMS = (
    Param('bag_path', '', 'Bag directory (or .mcap / .db3 file) to play', read_only=True),
    *shared_params('rate_factor'),
    Param('topics', [''], 'Topics to play; [""] for every topic in the bag', read_only=True),
    Param(
        'tick_s', 0.005, 'Timer period of the pacing loop [s]', limits=(1e-4, 1.0), read_only=True
    ),
    *SOURCE_PARAMS,
    CLOCK_PARAM,
)
# The package's topics: played under their relative names, whatever namespace recorded them.
FMM_TOPICS = (FORCE_TOPIC, VELOCITY_TOPIC, APPLIED_FORCE_TOPIC, IMPACTS_TOPIC, FRF_TOPIC)


def played_name(recorded: str) -> str:
    """The name a recorded topic is played on: an fmm topic's relative name, else itself."""
    return next((name for name in FMM_TOPICS if recorded.endswith('/' + name)), recorded)


class Player(Node):
    """Publishes a bag's messages (raw) on their topics, in recorded order and pace."""

    def __init__(self, **kwargs) -> None:
        super().__init__('player', **kwargs)
        self.config = declare_parameters(self, PARAMS)
        if not self.config['bag_path']:
            raise BadInputError('player: set the bag_path parameter to the bag to play')
        self.reader = BagReader(self.config['bag_path'], strict=False)
        self.reader.open()
        wanted = [topic for topic in self.config['topics'] if topic] or list(self.reader.topics)
        missing = sorted(set(wanted) - set(self.reader.topics))
        if missing:
            self.reader.close()
            raise BadInputError(
                f'bag {self.config["bag_path"]} has no topic {", ".join(missing)}; '
                f'it has {", ".join(sorted(self.reader.topics))}'
            )
        self._topic_publishers = {}
        for topic in wanted:
            msgtype, name = self.reader.topics[topic].msgtype, played_name(topic)
            # An fmm topic is played with the QoS its own publisher offers (KNOWN_TOPICS).
            default = SAMPLE_QOS if msgtype == SAMPLE_BATCH else RESULT_QOS
            qos = KNOWN_TOPICS.get(name, (msgtype, default))[1]
            self._topic_publishers[topic] = self.create_publisher(message_class(msgtype), name, qos)
        self._batch_topics = {
            topic for topic in wanted if self.reader.topics[topic].msgtype == SAMPLE_BATCH
        }
        self.source = PacedSource(
            self,
            [self._topic_publishers[topic] for topic in self._batch_topics],
            self.config,
            batches_per_s=1.0,  # paced by log time below; the source gives start and window
            window_samples=1,
            pace_label=f'x{self.config["rate_factor"]:g}',
            release=self._on_tick,
        )
        # A bag that recorded /clock plays it; an older one gets it from the batches' stamps.
        self.clock = ClockPublisher(
            self, self.config['publish_clock'] and CLOCK_TOPIC not in self.reader.topics
        )
        self._messages = self.reader.messages(wanted)
        self._next = next(self._messages, None)
        self.messages_played = 0
        self._anchor: tuple[float, int] | None = None
        self.create_timer(self.config['tick_s'], self._on_tick)
        total = sum(self.reader.topics[topic].count for topic in wanted)
        Health(self).add(
            'player',
            lambda: (
                OK if self.source.gate.started else WARN,
                f'{self.messages_played} of {total} messages played'
                + (
                    f', held back by {self.source.gate.holding_for}'
                    if self.source.gate.holding_for
                    else ''
                ),
                {'messages played': self.messages_played, 'messages in bag': total},
            ),
        )
        self.get_logger().info(
            f'playing {total} messages on {", ".join(wanted)} from '
            f'{self.config["bag_path"]} at x{self.config["rate_factor"]:g}'
        )

    @property
    def finished(self) -> bool:
        """True once every message has been published."""
        return self._next is None

    def _on_tick(self) -> None:
        if self._next is None or not self.source.ready():
            return
        now = time.monotonic()
        if self._anchor is None:
            self._anchor = (now, self._next.log_time_ns)
        wall0, log0 = self._anchor
        due_ns = log0 + (now - wall0) * 1e9 * self.config['rate_factor']
        sent = 0
        while self._next is not None and self._next.log_time_ns <= due_ns:
            if sent == MAX_MESSAGES_PER_TICK or not self._within_window(self._next):
                break  # the next report or tick goes on from here
            self._topic_publishers[self._next.topic].publish(bytes(self._next.data))
            self.messages_played += 1
            sent += 1
            self._next = next(self._messages, None)
        # As BatchPacer: a stall up to CATCH_UP_S is made up; further behind, re-anchored.
        behind_s = 0.0 if self._next is None else (due_ns - self._next.log_time_ns) * 1e-9
        if behind_s > CATCH_UP_S * self.config['rate_factor']:
            self._anchor = (now, self._next.log_time_ns)
            self.get_logger().warning(
                f'cannot keep x{self.config["rate_factor"]:g}: playing slower',
                throttle_duration_sec=10.0,
            )
        if self._next is None:
            self.get_logger().info(f'bag played: {self.messages_played} messages')
            for problem in self.reader.problems:
                self.get_logger().warning(f'bag: {problem}')

    def _within_window(self, message) -> bool:
        """For a SampleBatch: whether it keeps every consumer within the flow window."""
        if message.topic not in self._batch_topics:
            return True
        batch = self.reader.decode(message)
        first, end = batch.first_sample_index, batch.first_sample_index + len(batch.samples)
        gate = self.source.gate
        if first < gate.first_index or end < gate.published_end - len(batch.samples):
            gate.begin(first)  # the recording's next acquisition (index back)
        samples = len(batch.samples)
        window = self.source.window_now(
            samples,
            PacedSource.window_samples(self.config, batch.sample_rate_hz, samples),
            batch.sample_rate_hz,
        )
        if not gate.allows(end, window):
            return False
        gate.sent(end)
        stamp_ns = batch.header.stamp.sec * 1_000_000_000 + batch.header.stamp.nanosec
        if stamp_ns:
            self.clock.advance(stamp_ns + round(len(batch.samples) / batch.sample_rate_hz * 1e9))
        return True

    def destroy_node(self) -> None:
        """Deliver the last batches and close the bag before the node goes."""
        self.source.finish()
        self.reader.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """`ros2 run fmm_ros player --ros-args -p bag_path:=<bag>`."""
    return run_node(Player, args)


if __name__ == '__main__':
    main()
