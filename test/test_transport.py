"""Messages cross an in-process ROS graph intact and cheaply."""

import array
import threading

import numpy as np
import pytest
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

from fmm_interfaces.msg import SampleBatch
from fmm_interfaces.srv import FitFriction
from fmm_ros.constants import FORCE
from fmm_ros.ros import msgs

pytestmark = pytest.mark.ros

QOS = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)


class _Collector(Node):
    def __init__(self, **kwargs):
        super().__init__('collector', **kwargs)
        self.received: list[SampleBatch] = []
        self.arrived = threading.Event()
        self.create_subscription(SampleBatch, '/fmm/force', self._on_batch, QOS)

    def _on_batch(self, msg: SampleBatch) -> None:
        self.received.append(msg)
        self.arrived.set()


def test_sample_batch_of_500_float64_arrives_bit_identical(ros_graph):
    rng = np.random.default_rng(7)
    # Values chosen to catch any float32 or text round trip: full-precision randoms,
    # subnormal, extremes and a negative zero.
    samples = rng.normal(0.0, 300.0, 500)
    samples[:4] = [5e-324, 1.7976931348623157e308, -0.0, np.pi]
    collector = ros_graph.add(_Collector)
    talker = ros_graph.add(Node, node_name='talker')
    publisher = talker.create_publisher(SampleBatch, '/fmm/force', QOS)
    ros_graph.start()
    msg = msgs.sample_batch(
        samples,
        quantity=FORCE,
        sample_rate_hz=10_000.0,
        first_sample_index=1_000_000,
        stamp=talker.get_clock().now().to_msg(),
        frame_id='hammer',
        full_scale=2224.0,
    )
    for _ in range(100):  # discovery takes a moment: publish until the first one lands
        publisher.publish(msg)
        if collector.arrived.wait(0.1):
            break
    assert collector.received, 'no SampleBatch arrived within 10 s'
    got = collector.received[0]
    assert isinstance(got.samples, array.array) and got.samples.typecode == 'd'
    view = msgs.field_array(got.samples)
    assert view.base is not None and np.shares_memory(view, np.frombuffer(got.samples))
    assert view.tobytes() == samples.tobytes()
    assert (got.quantity, got.unit, got.sample_rate_hz) == ('force', 'N', 10_000.0)
    assert (got.first_sample_index, got.full_scale, got.header.frame_id) == (
        1_000_000,
        2224.0,
        'hammer',
    )


def test_float64_field_round_trip_copies_once_and_views_without_copy():
    values = np.linspace(-1.0, 1.0, 330_000)
    field = msgs.float64_field(values)
    view = msgs.field_array(field)
    assert view.tobytes() == values.tobytes()
    assert np.shares_memory(view, np.frombuffer(field))
    assert not view.flags.writeable


class _EchoFitter(Node):
    """A FitFriction server that echoes the request into the response: tests the transport."""

    def __init__(self, **kwargs):
        super().__init__('echo_fitter', **kwargs)
        self.create_service(FitFriction, '/fmm/fit_friction', self._on_request)

    def _on_request(self, request, response):
        response.success = True
        response.message = f'{len(request.impact_ids)} impacts, misfit {request.misfit}'
        response.mu = (request.mu_min + request.mu_max) / 2
        response.impact_ids = request.impact_ids
        response.per_impact_mu = msgs.float64_field(np.full(len(request.impact_ids), response.mu))
        return response


def test_fit_friction_request_response_round_trip(ros_graph):
    ros_graph.add(_EchoFitter)
    caller = ros_graph.add(Node, node_name='caller')
    client = caller.create_client(FitFriction, '/fmm/fit_friction')
    ros_graph.start()
    request = FitFriction.Request(
        impact_ids=[3, 4, 9], fit_damping=True, mu_min=0.05, mu_max=0.2, misfit='time'
    )
    response = ros_graph.call(client, request)
    assert response.success
    assert response.message == '3 impacts, misfit time'
    assert list(response.impact_ids) == [3, 4, 9]
    assert response.mu == 0.125
    assert msgs.field_array(response.per_impact_mu).tolist() == [0.125] * 3
