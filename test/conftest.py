"""Shared fixtures: a fresh private ROS graph per test (own Context, LOCALHOST discovery).

`make test` runs the suite on every core with pytest-xdist (`--dist loadgroup`): tests go to
whichever worker is free, except that the tests sharing a module-scoped fixture are kept on
one worker (`pytest_collection_modifyitems` below), so an expensive fixture (a site build,
a simulated campaign) is built once. Each worker draws its ROS domain ids from its own share
(`fmm_ros.ros.graph.private_domain_ids`), and servers bind port 0 or a free port.

matplotlib keeps its font cache in the repo's (ignored) .pytest_cache rather than the user's
home: tests write nothing outside the checkout and the temporary directory. Workers share it
safely: matplotlib writes the cache under a lock file, and numba replaces its cache files
atomically.
"""

import os
from pathlib import Path

import pytest

os.environ.setdefault(
    'MPLCONFIGDIR', str(Path(__file__).resolve().parents[1] / '.pytest_cache' / 'matplotlib')
)

SHARED_SCOPES = ('package', 'module', 'class')
"""Fixture scopes whose value tests share: their tests stay on one xdist worker."""


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Group each test that uses a fixture shared beyond one test with its file's other such
    tests (xdist_group, read by `--dist loadgroup`; without xdist the mark does nothing), and
    put the slow tests first.

    tryfirst: xdist reads the groups in its own hook of the same name.
    """
    for item in items:
        definitions = getattr(item, '_fixtureinfo', None)
        if definitions is None:
            continue
        shared = any(
            defs and defs[-1].scope in SHARED_SCOPES
            for defs in definitions.name2fixturedefs.values()
        )
        if shared:
            item.add_marker(pytest.mark.xdist_group(item.path.name))
    # The slow tests first (stable: each file's order kept), so that on two workers the
    # quick ones fill the end rather than one long quick-run benchmark starting last.
    items.sort(key=lambda item: item.get_closest_marker('slow') is None)


@pytest.fixture
def ros_graph():
    """An InProcessGraph torn down in the safe order after the test, whatever happens."""
    from fmm_ros.ros.graph import InProcessGraph

    with InProcessGraph() as graph:
        yield graph
