"""Shared fixtures: a fresh private ROS graph per test (own Context, LOCALHOST discovery).

matplotlib keeps its font cache in the repo's (ignored) .pytest_cache rather than the user's
home: tests write nothing outside the checkout and the temporary directory.
"""

import os
from pathlib import Path

import pytest

os.environ.setdefault(
    'MPLCONFIGDIR', str(Path(__file__).resolve().parents[1] / '.pytest_cache' / 'matplotlib')
)


@pytest.fixture
def ros_graph():
    """An InProcessGraph torn down in the safe order after the test, whatever happens."""
    from fmm_ros.ros.graph import InProcessGraph

    with InProcessGraph() as graph:
        yield graph
