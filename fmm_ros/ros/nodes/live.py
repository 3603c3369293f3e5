"""live: force and velocity decimated for live plots, one stamped point per message.

Foxglove, PlotJuggler and the station page plot one number per message against its stamp;
a SampleBatch of 500 samples is one point to them. This node turns each channel into
`points_per_s` DisplayPoints a second of signal on fmm/live/force and fmm/live/velocity
(`LIVE_TOPICS`): each the peak of its interval (sign kept) with the interval's envelope,
stamped in signal time like the batches (`core/signal/display.py`).

A viewer, not a consumer the rig waits for: it reports no stream progress, so a slow plot can
never hold a source back; behind by more than the queue, it drops batches and the plot shows
a gap. At 50 points a second it publishes 100 messages a second of signal (2,000 at x20), each
batch as a burst of points: its viewers' queue (`DISPLAY_QOS`) holds two seconds of them.
"""

from rclpy.node import Node

from fmm_interfaces.msg import DisplayPoint, SampleBatch
from fmm_ros.constants import CHANNELS, FORCE_TOPIC, LIVE_TOPICS, VELOCITY_TOPIC
from fmm_ros.core.signal import display
from fmm_ros.ros import msgs
from fmm_ros.ros.common import run_node
from fmm_ros.ros.health import OK, Health
from fmm_ros.ros.params import Param, declare_parameters
from fmm_ros.ros.qos import DISPLAY_QOS, VIEW_SAMPLE_QOS

PARAMS = (
    Param(
        'points_per_s',
        50.0,
        'Points per second of signal on each live topic [1/s] (peak of each interval kept)',
        limits=(0.1, 10_000.0),
        read_only=True,
    ),
)

SOURCE_TOPICS = {FORCE_TOPIC: CHANNELS[0], VELOCITY_TOPIC: CHANNELS[1]}


class Live(Node):
    """Subscribes to the sample batches, publishes each channel's decimated points."""

    def __init__(self, **kwargs) -> None:
        super().__init__('live', **kwargs)
        self.config = declare_parameters(self, PARAMS)
        self._decimators: dict[str, tuple[float, display.PeakDecimator]] = {}
        self.points_published = {channel.quantity: 0 for channel in CHANNELS}
        self._outputs = {
            channel.quantity: self.create_publisher(
                DisplayPoint, LIVE_TOPICS[channel.quantity], DISPLAY_QOS
            )
            for channel in CHANNELS
        }
        for topic, channel in SOURCE_TOPICS.items():
            self.create_subscription(
                SampleBatch,
                topic,
                lambda msg, channel=channel: self._on_batch(channel, msg),
                VIEW_SAMPLE_QOS,
            )
        Health(self).add(
            'live',
            lambda: (
                OK,
                ', '.join(f'{n} {q} points' for q, n in self.points_published.items()),
                {f'{q} points published': n for q, n in self.points_published.items()},
            ),
        )
        self.get_logger().info(
            f'{self.config["points_per_s"]:g} points/s of signal on '
            f'{", ".join(self.resolve_topic_name(t) for t in LIVE_TOPICS.values())}'
        )

    def _decimator(self, quantity: str, sample_rate_hz: float) -> display.PeakDecimator:
        """The channel's decimator; a new one when the sample rate changes (a new acquisition)."""
        rate, decimator = self._decimators.get(quantity, (None, None))
        if rate != sample_rate_hz:
            decimator = display.PeakDecimator(
                display.samples_per_point(sample_rate_hz, self.config['points_per_s'])
            )
            self._decimators[quantity] = (sample_rate_hz, decimator)
        return decimator

    def _on_batch(self, channel, msg: SampleBatch) -> None:
        if not msg.sample_rate_hz > 0:
            return  # malformed: no time axis to decimate on (the analyzer logs and counts it)
        batch = msgs.stream_batch(msg)
        decimator = self._decimator(channel.quantity, msg.sample_rate_hz)
        publisher = self._outputs[channel.quantity]
        for point in decimator.feed(batch.first_sample_index, batch.samples):
            offset_ns = round(
                (point.first_sample_index - batch.first_sample_index) / msg.sample_rate_hz * 1e9
            )
            out = DisplayPoint()
            out.header.stamp = msgs.time_msg(max(0, batch.stamp_ns + offset_ns))
            out.header.frame_id = msg.header.frame_id
            out.quantity, out.unit = channel
            out.first_sample_index = point.first_sample_index
            out.sample_count = point.sample_count
            out.value, out.minimum, out.maximum = point.value, point.minimum, point.maximum
            publisher.publish(out)
            self.points_published[channel.quantity] += 1


def main(args: list[str] | None = None) -> int:
    """`ros2 run fmm_ros live`."""
    return run_node(Live, args)


if __name__ == '__main__':
    main()
