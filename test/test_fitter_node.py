"""fitter node: fits the impacts the analyzer reports, from its own stream history."""

import pytest
from rclpy.node import Node
from rig_graph import FAST_ANALYZER, FAST_HAMMER, Listener, params, wait_for

from fmm_interfaces.srv import FitFriction
from fmm_ros.constants import FIT_SERVICE, PAPER_MU
from fmm_ros.ros import msgs
from fmm_ros.ros.nodes.analyzer import Analyzer
from fmm_ros.ros.nodes.fitter import Fitter
from fmm_ros.ros.nodes.hammer_sim import HammerSim
from fmm_ros.ros.nodes.rig_sim import RigSim

pytestmark = pytest.mark.ros


def fit_client(graph):
    return graph.add(Node, node_name='caller').create_client(FitFriction, FIT_SERVICE)


def test_the_session_fit_recovers_the_plant_mu(ros_graph):
    ros_graph.add(HammerSim, parameter_overrides=params(**FAST_HAMMER))
    ros_graph.add(RigSim)
    ros_graph.add(Analyzer, parameter_overrides=params(**FAST_ANALYZER))
    fitter = ros_graph.add(Fitter)
    listener = ros_graph.add(Listener)
    client = fit_client(ros_graph)
    ros_graph.start()
    assert wait_for(lambda: len(fitter.impacts) == 3), f'{len(listener.impacts)} reported'
    response = ros_graph.call(client, FitFriction.Request(), timeout_s=60.0)
    assert response.success, response.message
    assert response.mu == pytest.approx(PAPER_MU, rel=0.02)
    assert 0 < response.mu_stderr < 0.01 * response.mu
    assert list(response.impact_ids) == [0, 1, 2]
    per_impact = msgs.field_array(response.per_impact_mu)
    assert per_impact == pytest.approx([PAPER_MU] * 3, rel=0.03)
    impulses = msgs.field_array(response.per_impact_impulse_n_s)
    assert impulses == pytest.approx([m.impulse_n_s for m in listener.impacts], rel=0.01)
    assert 0 < response.residual_normalized < 0.01


def test_requests_without_data_are_answered_with_the_reason(ros_graph):
    ros_graph.add(Fitter)
    client = fit_client(ros_graph)
    ros_graph.start()
    response = ros_graph.call(client, FitFriction.Request())
    assert (response.success, response.message) == (
        False,
        'no impact held yet (0 still arriving)',
    )
    response = ros_graph.call(client, FitFriction.Request(impact_ids=[4, 7]))
    assert not response.success and 'impacts [4, 7] are not held' in response.message
