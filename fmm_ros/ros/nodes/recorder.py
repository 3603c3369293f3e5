"""recorder: writes live topics to a rosbag2 bag (MCAP by default) with the rosbags library.

Subscribes raw (rclpy hands over the serialized CDR bytes) and stores those bytes as they
came, so recording costs no decode/encode. The fmm topics are subscribed at once with their
known types and QoS (nothing is missed while the graph is discovered); any other topic's
type is read from the graph when a publisher appears, with the subscription QoS following
what the publishers offer, as `ros2 bag record` does. The writer flushes every
`flush_interval_s`, so a crash loses at most that much.
"""

import time
from datetime import datetime
from pathlib import Path

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from fmm_ros.constants import (
    APPLIED_FORCE_TOPIC,
    FORCE_TOPIC,
    FRF_TOPIC,
    FRICTION_TOPIC,
    IMPACTS_TOPIC,
    VELOCITY_TOPIC,
)
from fmm_ros.io.bags.writer import STORAGES, BagWriter, bag_qos
from fmm_ros.ros.common import RESULT_QOS, SAMPLE_QOS, message_class, run_node
from fmm_ros.ros.params import Param, declare_parameters

PARAMS = (
    Param(
        'topics',
        [FORCE_TOPIC, VELOCITY_TOPIC, IMPACTS_TOPIC, FRF_TOPIC, FRICTION_TOPIC],
        'Topics to record',
        read_only=True,
    ),
    Param('bag_path', '', 'Bag directory to create; "" for fmm_<date>_<time> here', read_only=True),
    Param('storage', 'mcap', 'rosbag2 storage plugin', choices=tuple(STORAGES), read_only=True),
    Param(
        'flush_interval_s',
        1.0,
        'Longest stretch of recording a crash can lose [s]',
        limits=(0.01, 3600.0),
        read_only=True,
    ),
    Param(
        'discovery_period_s',
        0.5,
        'How often topics not seen yet are looked for [s]',
        limits=(0.01, 60.0),
        read_only=True,
    ),
)

# Topics of this package: type and the QoS their publishers offer.
KNOWN_TOPICS = {
    FORCE_TOPIC: ('fmm_interfaces/msg/SampleBatch', SAMPLE_QOS),
    VELOCITY_TOPIC: ('fmm_interfaces/msg/SampleBatch', SAMPLE_QOS),
    APPLIED_FORCE_TOPIC: ('fmm_interfaces/msg/SampleBatch', SAMPLE_QOS),
    IMPACTS_TOPIC: ('fmm_interfaces/msg/ImpactResult', RESULT_QOS),
    FRF_TOPIC: ('fmm_interfaces/msg/FrfSummary', RESULT_QOS),
    FRICTION_TOPIC: ('fmm_interfaces/msg/FrictionEstimate', RESULT_QOS),
}


class Recorder(Node):
    """Raw subscriptions on the chosen topics, each message stored as received."""

    def __init__(self, **kwargs) -> None:
        super().__init__('recorder', **kwargs)
        self.config = declare_parameters(self, PARAMS)
        path = self.config['bag_path'] or datetime.now().strftime('fmm_%Y%m%d_%H%M%S')
        self.writer = BagWriter(
            Path(path),
            storage=self.config['storage'],
            flush_interval_s=self.config['flush_interval_s'],
        )
        self.writer.open()
        self.bag_path = self.writer.path
        self.messages_recorded = 0
        self._pending = []
        self._raw_subscriptions = []
        for topic in filter(None, self.config['topics']):
            if topic in KNOWN_TOPICS:
                self._subscribe(topic, *KNOWN_TOPICS[topic])
            else:
                self._pending.append(topic)
        self._discover()
        self._timer = self.create_timer(self.config['discovery_period_s'], self._discover)
        recorded = [sub.topic_name for sub in self._raw_subscriptions]
        self.get_logger().info(
            f'recording {", ".join(recorded) or "nothing yet"} to {self.bag_path} '
            f'({self.config["storage"]})'
            + (f'; waiting for {", ".join(self._pending)}' if self._pending else '')
        )

    @property
    def waiting_for(self) -> list[str]:
        """Topics asked for that no publisher has offered yet."""
        return list(self._pending)

    def _discover(self) -> None:
        """Subscribe to every pending topic that now has a publisher."""
        for topic in list(self._pending):
            publishers = self.get_publishers_info_by_topic(topic)
            types = {info.topic_type for info in publishers}
            if not types:
                continue
            if len(types) > 1:
                self.get_logger().error(
                    f'{topic} is published with several types {types}: not recorded',
                    throttle_duration_sec=30.0,
                )
                continue
            self._subscribe(
                topic, types.pop(), _subscription_qos([info.qos_profile for info in publishers])
            )
            self._pending.remove(topic)

    def _subscribe(self, topic: str, msgtype: str, qos: QoSProfile) -> None:
        self.writer.add_topic(
            topic,
            msgtype,
            qos=bag_qos(
                depth=qos.depth,
                reliable=qos.reliability == ReliabilityPolicy.RELIABLE,
                transient_local=qos.durability == DurabilityPolicy.TRANSIENT_LOCAL,
            ),
        )
        self._raw_subscriptions.append(
            self.create_subscription(
                message_class(msgtype),
                topic,
                lambda data, topic=topic, msgtype=msgtype: self._store(topic, msgtype, data),
                qos,
                raw=True,
            )
        )

    def _store(self, topic: str, msgtype: str, data: bytes) -> None:
        self.writer.write_raw(topic, msgtype, data, time.time_ns())
        self.messages_recorded += 1

    def destroy_node(self) -> None:
        """Close the bag (MCAP summary, metadata.yaml) before the node goes."""
        self.writer.close()
        super().destroy_node()


def _subscription_qos(offered: list[QoSProfile]) -> QoSProfile:
    """The strongest QoS every publisher can serve, with a deep queue (as ros2 bag record)."""
    reliable = all(q.reliability == ReliabilityPolicy.RELIABLE for q in offered)
    durable = all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered)
    return QoSProfile(
        depth=1000,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if durable else DurabilityPolicy.VOLATILE,
    )


def main(args: list[str] | None = None) -> None:
    """`ros2 run fmm_ros recorder`."""
    run_node(Recorder, args)


if __name__ == '__main__':
    main()
