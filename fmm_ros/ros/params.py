"""Declare a node's parameters from one table: description with unit, range, choices, read-only.

Tables are written as `Param` entries, or made from the core's declared settings (`params_from`), so
a capture or rig setting has one default, unit, range and help in the package. The params
file of every node is written above the nodes, by `fmm_ros.ros.params_file`.

ROS descriptors carry numeric ranges for scalars only; ranges on float arrays and the
allowed values of string parameters are enforced here by an on-set callback registered
before declaration, so a bad value from a params file is refused at start-up with a reason
(rclpy raises InvalidParameterValueException) and a bad live `set_parameters` is refused
the same way without touching the running node.
"""

from collections.abc import Sequence
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

from fmm_ros.core.settings import settings_of

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


def params_from(
    settings: type | object, names: Sequence[str] | None = None, *, read_only: bool = True
) -> tuple[Param, ...]:
    """The parameters of declared settings (`fmm_ros.core.settings`): one per field in names.

    settings: a settings dataclass, or an instance whose values become the defaults; names:
    the fields a node exposes (default: all). A tuple becomes a list; an optional number
    (None: off) becomes 0.0, '0 for none', as ROS parameters cannot be None.
    """
    declared = {item.name: item for item in settings_of(settings)}
    params = []
    for name in names or tuple(declared):
        item = declared[name]
        default, description = item.default, item.described
        if default is None:
            default, description = 0.0, f'{description}; 0 for none'
        elif isinstance(default, tuple):
            default = list(default)
        choices = item.choices if isinstance(default, str) else ()
        params.append(Param(name, default, description, item.limits, choices, read_only))
    return tuple(params)


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
