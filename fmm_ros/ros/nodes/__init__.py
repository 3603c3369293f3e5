"""ROS 2 nodes: each module holds one node class and a `main()` for `ros2 run fmm_ros <node>`.

`NODES` is the one list of them (node name -> class name): the launcher starts them by it and
the params file is generated from their `PARAMS` tables by it. Modules are imported on demand,
so starting one node never imports the others.
"""

import importlib
from types import ModuleType

from fmm_ros.errors import BadInputError

NODES: dict[str, str] = {
    'hammer_sim': 'HammerSim',
    'rig_sim': 'RigSim',
    'daq': 'Daq',
    'analyzer': 'Analyzer',
    'fitter': 'Fitter',
    'recorder': 'Recorder',
    'player': 'Player',
}


# Who takes each source's sample batches in a rig: the nodes a source waits for before its
# first sample (`wait_for_consumers`), as the launcher and the params file set it.
CONSUMERS: dict[str, tuple[str, ...]] = {
    'hammer_sim': ('rig_sim', 'analyzer', 'fitter', 'recorder'),
    'rig_sim': ('analyzer', 'fitter', 'recorder'),
    'daq': ('analyzer', 'fitter', 'recorder'),
    'player': ('analyzer', 'fitter', 'recorder'),
}


def node_module(name: str) -> ModuleType:
    """The module of node `name` (ValueError naming the known nodes for any other name)."""
    if name not in NODES:
        raise BadInputError(f'no fmm_ros node {name!r}; the nodes are {", ".join(NODES)}')
    return importlib.import_module(f'{__name__}.{name}')


def node_class(name: str) -> type:
    """The node class of node `name`."""
    return getattr(node_module(name), NODES[name])
