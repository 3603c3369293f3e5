"""foxglove_server: the rig's live topics served to Foxglove over its WebSocket protocol.

Opt in with `fmm foxglove` (this node and the live node) or `ros2 run fmm_ros foxglove_server`.
It runs the Foxglove SDK's WebSocket server (`foxglove-sdk`), bound to 127.0.0.1:8765 by
default, and forwards each topic in `topics` as it arrives: raw subscriptions, the CDR bytes
passed on unchanged with the topic's ros2msg definition (from fmm_interfaces' .msg files and
the ROS Jazzy types), so Foxglove decodes them as it decodes a foxglove_bridge or a bag, and
this node never decodes a message. Each message's log time is its header stamp, and the
server's time is /clock: both signal time (`fmm_ros.ros.timebase`), so Foxglove's timeline
and plots line every topic up at any rate_factor.

A viewer, not a consumer the rig waits for: it reports no stream progress; a browser that
cannot keep up loses the oldest messages in the server's per-client queue, never the rig's.
Open config/foxglove/fmm_rig_layout.json in Foxglove for the rig's panels.
"""

import struct

import foxglove
from foxglove.websocket import Capability, ChannelView, Client
from rclpy.node import Node

from fmm_ros.constants import (
    CLOCK_TOPIC,
    DIAGNOSTICS_TOPIC,
    FORCE_TOPIC,
    FRF_TOPIC,
    FRICTION_TOPIC,
    IMPACTS_TOPIC,
    LIVE_TOPICS,
    VELOCITY_TOPIC,
)
from fmm_ros.errors import BadInputError
from fmm_ros.io.bags.definitions import fmm_typestore
from fmm_ros.ros.common import message_class, run_node, shared_params
from fmm_ros.ros.health import OK, WARN, Health
from fmm_ros.ros.nodes.recorder import KNOWN_TOPICS
from fmm_ros.ros.params import Param, declare_parameters

SERVED_TOPICS = (
    *LIVE_TOPICS.values(),
    IMPACTS_TOPIC,
    FRICTION_TOPIC,
    FRF_TOPIC,
    FORCE_TOPIC,
    VELOCITY_TOPIC,
    DIAGNOSTICS_TOPIC,
    CLOCK_TOPIC,
)
"""What the server offers by default: every fmm result and stream, health and signal time."""

PARAMS = (
    *shared_params('host', 'port', port=8765),
    Param(
        'topics',
        list(SERVED_TOPICS),
        'Topics to serve (fmm topics, /diagnostics, /clock)',
        read_only=True,
    ),
    Param(
        'queue_messages',
        1024,
        'Messages queued per client before its oldest are dropped [-]',
        limits=(16, 1_000_000),
        read_only=True,
    ),
)

_LE_CDR = (b'\x00\x01', b'\x00\x03')  # encapsulation ids of little-endian CDR and PL_CDR


def leading_stamp_ns(cdr: bytes) -> int | None:
    """The builtin_interfaces/Time a serialized message starts with [ns], or None.

    Every topic served starts with one (a std_msgs/Header's stamp, or Clock.clock), so the
    log time is read from the bytes without decoding the message.
    """
    if len(cdr) < 12 or cdr[:2] not in _LE_CDR:
        return None
    sec, nanosec = struct.unpack_from('<iI', cdr, 4)
    return sec * 1_000_000_000 + nanosec if sec >= 0 else None


class _Subscriptions:
    """The server's listener: counts what Foxglove clients are subscribed to."""

    def __init__(self) -> None:
        self.count = 0
        self.clients: set[int] = set()

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self.count += 1
        self.clients.add(client.id)

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        self.count = max(0, self.count - 1)


class FoxgloveServer(Node):
    """Serves the chosen topics to Foxglove clients, raw CDR with ros2msg schemas."""

    def __init__(self, **kwargs) -> None:
        super().__init__('foxglove_server', **kwargs)
        self.config = declare_parameters(self, PARAMS)
        topics = [topic for topic in self.config['topics'] if topic]
        unknown = [topic for topic in topics if topic not in KNOWN_TOPICS]
        if unknown:
            raise BadInputError(
                f'foxglove_server: no known type for {", ".join(unknown)}; '
                f'the topics it serves are {", ".join(KNOWN_TOPICS)}'
            )
        self._foxglove_context = foxglove.Context()
        self.listener = _Subscriptions()
        try:
            self.server = foxglove.start_server(
                name=f'fmm_ros {self.get_fully_qualified_name()}',
                host=self.config['host'],
                port=self.config['port'],
                capabilities=[Capability.Time],
                server_listener=self.listener,
                context=self._foxglove_context,
                message_backlog_size=self.config['queue_messages'],
            )
        except RuntimeError as error:  # the SDK's FoxgloveError: bind failed, bad address
            raise BadInputError(
                f'foxglove_server: cannot serve on {self.config["host"]}:{self.config["port"]}: '
                f'{error} (another server there? choose another port)'
            ) from error
        self.messages_forwarded = 0
        typestore = fmm_typestore()
        self._channels = {}
        for topic in topics:
            msgtype, qos = KNOWN_TOPICS[topic]
            resolved = self.resolve_topic_name(topic)
            definition, _ = typestore.generate_msgdef(msgtype, ros_version=2)
            self._channels[resolved] = foxglove.Channel(
                resolved,
                schema=foxglove.Schema(name=msgtype, encoding='ros2msg', data=definition.encode()),
                message_encoding='cdr',
                context=self._foxglove_context,
            )
            self.create_subscription(
                message_class(msgtype),
                resolved,
                lambda data, topic=resolved: self._forward(topic, data),
                qos,
                raw=True,
            )
        Health(self).add('foxglove', self._status)
        self.get_logger().info(
            f'Foxglove WebSocket server on ws://{self.config["host"]}:{self.server.port} '
            f'serving {", ".join(self._channels)}'
        )

    @property
    def port(self) -> int:
        """The port the server listens on (the one chosen when `port` is 0)."""
        return self.server.port

    def _forward(self, topic: str, data: bytes) -> None:
        stamp_ns = leading_stamp_ns(data)
        self._channels[topic].log(data, log_time=stamp_ns)
        self.messages_forwarded += 1
        if topic.endswith(CLOCK_TOPIC) and stamp_ns is not None:
            self.server.broadcast_time(stamp_ns)

    def _status(self) -> tuple:
        return (
            OK if self.server.port else WARN,
            f'ws://{self.config["host"]}:{self.server.port}, {self.listener.count} '
            f'subscriptions, {self.messages_forwarded} messages forwarded',
            {
                'url': f'ws://{self.config["host"]}:{self.server.port}',
                'subscriptions': self.listener.count,
                'clients seen': len(self.listener.clients),
                'messages forwarded': self.messages_forwarded,
            },
        )

    def destroy_node(self) -> None:
        """Close the server (clients see it go) before the node goes."""
        self.server.stop()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """`ros2 run fmm_ros foxglove_server`."""
    return run_node(FoxgloveServer, args)


if __name__ == '__main__':
    main()
