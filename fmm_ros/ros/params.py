"""Declare a node's parameters from one table: description with unit, range, choices, read-only.

ROS descriptors carry numeric ranges for scalars only; ranges on float arrays and the
allowed values of string parameters are enforced here by an on-set callback registered
before declaration, so a bad value from a params file is refused at start-up with a reason
(rclpy raises InvalidParameterValueException) and a bad live `set_parameters` is refused
the same way without touching the running node.
"""

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import yaml
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.node import Node
from rclpy.parameter import Parameter

ParamValue = bool | int | float | str | list[float] | list[str] | list[int]


@dataclass(frozen=True)
class Param:
    """One node parameter. `limits` bounds a number or every element of a number array."""

    name: str
    default: ParamValue
    description: str
    limits: tuple[float, float] | None = None
    choices: tuple[str, ...] = ()
    read_only: bool = False

    def descriptor(self) -> ParameterDescriptor:
        """The ROS descriptor: what `ros2 param describe` shows.

        Float parameters are dynamically typed, so `rate_factor: 20` in a params file or
        `-p rate_factor:=20` is taken as 20.0 instead of refused for being an INTEGER; their
        type and range are then checked by `problem`.
        """
        descriptor = ParameterDescriptor(
            description=self.description, read_only=self.read_only, dynamic_typing=self._is_float
        )
        if self.limits is not None and isinstance(self.default, list):
            low, high = self.limits
            descriptor.additional_constraints = f'every element in [{low}, {high}]'
        elif self.limits is not None and isinstance(self.default, int):
            descriptor.integer_range = [
                IntegerRange(from_value=int(self.limits[0]), to_value=int(self.limits[1]), step=1)
            ]
        elif self.limits is not None:
            descriptor.floating_point_range = [
                FloatingPointRange(
                    from_value=float(self.limits[0]), to_value=float(self.limits[1]), step=0.0
                )
            ]
        if self.choices:
            descriptor.additional_constraints = f'one of {", ".join(self.choices)}'
        return descriptor

    @property
    def _is_float(self) -> bool:
        return isinstance(self.default, float)

    def problem(self, value: ParamValue) -> str | None:
        """Why value is not acceptable (checks ROS descriptors cannot express), or None."""
        if self._is_float:
            if isinstance(value, bool) or not isinstance(value, int | float):
                return f'{self.name} = {value!r} is not a number'
            if self.limits is not None and not self.limits[0] <= value <= self.limits[1]:
                return f'{self.name} = {value} out of range [{self.limits[0]}, {self.limits[1]}]'
        if self.choices and value not in self.choices:
            return f'{self.name} = {value!r} is not one of {", ".join(self.choices)}'
        if self.limits is not None and isinstance(value, list | tuple):
            low, high = self.limits
            bad = [item for item in value if not low <= item <= high]
            if bad:
                return f'{self.name} has {bad} outside [{low}, {high}]'
        return None

    def yaml_line(self, value: ParamValue | None = None) -> str:
        """`name: value  # description; range or choices`: a params file line (value: default)."""
        notes = []
        if self.limits is not None:
            low, high = (_number(limit, self.default) for limit in self.limits)
            notes.append(f'{"each " if isinstance(self.default, list) else ""}{low} to {high}')
        if self.choices:
            notes.append(f'one of {", ".join(self.choices)}')
        if not self.read_only:
            notes.append('settable live')
        if value is not None and value != self.default:
            notes.append(f'node default {_yaml_value(self.default)}')
        shown = self.default if value is None else value
        return f'{self.name}: {_yaml_value(shown)}  # {self.description}' + ''.join(
            f'; {note}' for note in notes
        )

    def value(self, parameter: Parameter) -> ParamValue:
        """The parameter's value in the default's type (an integer given for a float: float)."""
        return float(parameter.value) if self._is_float else parameter.value


def _yaml_value(value: ParamValue) -> str:
    """A value as YAML both rcl and PyYAML read back with its type.

    Strings in lists are always quoted, so `['no']` stays a string.
    """
    if isinstance(value, list):
        return (
            '['
            + ', '.join(
                "'" + item.replace("'", "''") + "'" if isinstance(item, str) else _yaml_value(item)
                for item in value
            )
            + ']'
        )
    if isinstance(value, float):
        value = float(f'{value:.12g}')  # 0.680 * 9.81 shown as 6.6708, not 6.670800000000001
    if isinstance(value, str) and value.lower() in ('y', 'n'):
        return f"'{value}'"  # rcl reads a bare y or n (a force in N) as a bool; PyYAML does not
    return yaml.safe_dump(value, default_flow_style=True).removesuffix('...\n').strip()


def _number(limit: float, default: ParamValue) -> str:
    """A range limit as people write it: an integer for integer parameters, 1e6 not 1e+06."""
    sample = default[0] if isinstance(default, list) and default else default
    if isinstance(sample, int) and not isinstance(sample, bool):
        return str(int(limit))
    return f'{limit:g}'.replace('e+0', 'e').replace('e+', 'e').replace('e-0', 'e-')


PARAMS_FILE_HEADER = """\
# fmm_ros parameters, in the standard `node_name: ros__parameters:` form.
# ros2 run fmm_ros <node> --ros-args --params-file config/fmm_rig.yaml
# Every value is the node's default (or names the default it replaces), with its description,
# unit [in brackets], range or choices, and whether it can be set on a running node (the
# others are read at start-up).
# Made from the PARAMS tables in fmm_ros/ros/nodes/<node>.py by
#   .venv/bin/python -m fmm_ros.ros.params > config/fmm_rig.yaml
"""


def _rig_values() -> dict[str, dict[str, ParamValue]]:
    """Where the package's params file departs from a node's default.

    In a rig the sources hold their first sample until the rig's other nodes (other
    processes, discovered later) take their batches, so nothing is lost at start-up.
    """
    from fmm_ros.ros.nodes import CONSUMERS

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
    from fmm_ros.ros.nodes import NODES, node_module

    return {name: node_module(name).PARAMS for name in NODES}


def declare_parameters(node: Node, params: Sequence[Param]) -> dict[str, ParamValue]:
    """Declare params on node (overrides from params files apply) and return their values."""
    by_name = {param.name: param for param in params}

    def check(parameters: list[Parameter]) -> SetParametersResult:
        for parameter in parameters:
            param = by_name.get(parameter.name)
            reason = param.problem(parameter.value) if param else None
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(check)
    for param in params:
        node.declare_parameter(param.name, param.default, param.descriptor())
    return {param.name: param.value(node.get_parameter(param.name)) for param in params}


if __name__ == '__main__':
    print(params_file_text(node_param_tables()), end='')
