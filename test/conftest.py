"""Shared fixtures: a fresh private ROS graph per test (own Context, LOCALHOST discovery)."""

import pytest


@pytest.fixture
def ros_graph():
    """An InProcessGraph torn down in the safe order after the test, whatever happens."""
    from fmm_ros.ros_graph import InProcessGraph

    with InProcessGraph() as graph:
        yield graph
