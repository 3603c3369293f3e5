"""One time base for the graph: signal time, which the source publishes on /clock.

Every fmm stamp is signal time. A source stamps sample i of an acquisition `start + i / rate`,
start being its wall clock when the acquisition began (hammer_sim, daq; the player plays the
recorded stamps); a result carries the stamp of the samples it describes (ImpactResult its
trigger, FrfSummary and FrictionEstimate the newest impact they hold; a DisplayPoint its
interval). At x1 signal time runs with the wall clock, at x20 twenty times faster, in a
replay it is the recording's time.

A source also publishes it on /clock (rosgraph_msgs/Clock, the ROS sim-time topic) as its
samples go out, at most `CLOCK_RATE_HZ` times a wall second, so that:

- /diagnostics, stamped by nodes that may see no samples at all, follow it (`SignalClock`);
- a bag records it, and a viewer (Foxglove, PlotJuggler, rqt) lines every topic up on one
  axis at any rate_factor;
- a node a lab adds can run with `use_sim_time:=true` and stamp in the same time.

As ROS sim time, it stands still while no samples go out. /clock is absolute, as ROS has it:
two rigs in one graph (namespaces) give one source `publish_clock:=false`, or use a domain each.
"""

import time

from rclpy.node import Node
from rosgraph_msgs.msg import Clock

from fmm_ros.constants import CLOCK_TOPIC
from fmm_ros.ros import msgs
from fmm_ros.ros.params import Param
from fmm_ros.ros.qos import CLOCK_QOS, CLOCK_SUBSCRIPTION_QOS

CLOCK_RATE_HZ = 50.0
"""Most /clock messages a source publishes per wall second (each batch moves the clock)."""

CLOCK_PARAM = Param(
    'publish_clock',
    True,
    'Publish signal time on /clock as samples go out (one source per graph does)',
    read_only=True,
)


class ClockPublisher:
    """A source's /clock: the signal time its published samples reach, rate-limited."""

    def __init__(self, node: Node, enabled: bool, rate_hz: float = CLOCK_RATE_HZ) -> None:
        self._publisher = node.create_publisher(Clock, CLOCK_TOPIC, CLOCK_QOS) if enabled else None
        self._period_s = 1.0 / rate_hz
        self._last_wall = -float('inf')
        self.last_ns: int | None = None

    def advance(self, signal_ns: int, *, force: bool = False) -> None:
        """The samples out now reach signal_ns; published unless one went out just now."""
        if self._publisher is None:
            return
        now = time.monotonic()
        if not force and now - self._last_wall < self._period_s:
            return
        self._last_wall = now
        self.last_ns = int(signal_ns)
        self._publisher.publish(Clock(clock=msgs.time_msg(int(signal_ns))))


class SignalClock:
    """What time it is in signal time for a node: the newest /clock, else its wall clock.

    Before any /clock arrives (no source yet, or one with publish_clock false) signal time is
    the wall clock, which the sources' stamps start from.
    """

    def __init__(self, node: Node) -> None:
        self._node = node
        self.last_ns: int | None = None
        node.create_subscription(Clock, CLOCK_TOPIC, self._on_clock, CLOCK_SUBSCRIPTION_QOS)

    def _on_clock(self, msg: Clock) -> None:
        self.last_ns = msgs.stamp_ns(msg.clock)

    def now_ns(self) -> int:
        """Signal time now [ns]."""
        if self.last_ns is None:
            return self._node.get_clock().now().nanoseconds
        return self.last_ns
