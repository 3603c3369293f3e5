"""The package's params file (config/fmm_rig.yaml): every node's parameters, made from PARAMS.

It sits above the nodes (it imports each node module's `PARAMS` by `fmm_ros.ros.nodes.NODES`),
so `fmm_ros.ros.params`, which the nodes import, imports no node.
Write it with `.venv/bin/python -m fmm_ros.ros.params_file > config/fmm_rig.yaml`; a test
compares the file with this text.
"""

from collections.abc import Mapping, Sequence

from fmm_ros.ros.nodes import CONSUMERS, NODES, node_module
from fmm_ros.ros.params import Param, ParamValue

PARAMS_FILE_HEADER = """\
# fmm_ros parameters, in the standard `node_name: ros__parameters:` form.
# ros2 run fmm_ros <node> --ros-args --params-file config/fmm_rig.yaml
# Every value is the node's default (or names the default it replaces), with its description,
# unit [in brackets], range or choices, and whether it can be set on a running node (the
# others are read at start-up).
# Made from the PARAMS tables in fmm_ros/ros/nodes/<node>.py by
#   .venv/bin/python -m fmm_ros.ros.params_file > config/fmm_rig.yaml
"""


def _rig_values() -> dict[str, dict[str, ParamValue]]:
    """Where the package's params file departs from a node's default.

    In a rig the sources hold their first sample until the rig's other nodes (other
    processes, discovered later) take their batches, so nothing is lost at start-up.
    """
    return {
        source: {'wait_for_consumers': list(CONSUMERS[source])}
        for source in ('hammer_sim', 'rig_sim', 'daq')
    }


PARAMS_FILE_VALUES = _rig_values()


def params_file_text(
    tables: Mapping[str, Sequence[Param]],
    values: Mapping[str, Mapping[str, ParamValue]] = PARAMS_FILE_VALUES,
) -> str:
    """A ROS params file of every node's parameters (config/fmm_rig.yaml is this text).

    Each holds its default except where values gives another.
    """
    blocks = [
        f'{node}:\n  ros__parameters:\n'
        + ''.join(
            f'    {param.yaml_line(values.get(node, {}).get(param.name))}\n' for param in params
        )
        for node, params in tables.items()
    ]
    return PARAMS_FILE_HEADER + '\n' + '\n'.join(blocks)


def node_param_tables() -> dict[str, Sequence[Param]]:
    """Every fmm_ros node's PARAMS table, by node name (`fmm_ros.ros.nodes.NODES`)."""
    return {name: node_module(name).PARAMS for name in NODES}


if __name__ == '__main__':
    print(params_file_text(node_param_tables()), end='')
