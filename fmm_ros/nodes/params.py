"""Declare a node's parameters from one table: description with unit, range, choices, read-only.

ROS descriptors carry numeric ranges for scalars only; ranges on float arrays and the
allowed values of string parameters are enforced here by an on-set callback registered
before declaration, so a bad value from a params file is refused at start-up with a reason
(rclpy raises InvalidParameterValueException) and a bad live `set_parameters` is refused
the same way without touching the running node.
"""

from collections.abc import Sequence
from dataclasses import dataclass

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
        descriptor = ParameterDescriptor(description=self.description, read_only=self.read_only,
                                         dynamic_typing=self._is_float)
        if self.limits is not None and isinstance(self.default, list):
            low, high = self.limits
            descriptor.additional_constraints = f'every element in [{low}, {high}]'
        elif self.limits is not None and isinstance(self.default, int):
            descriptor.integer_range = [IntegerRange(
                from_value=int(self.limits[0]), to_value=int(self.limits[1]), step=1)]
        elif self.limits is not None:
            descriptor.floating_point_range = [FloatingPointRange(
                from_value=float(self.limits[0]), to_value=float(self.limits[1]), step=0.0)]
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
                return (f'{self.name} = {value} out of range [{self.limits[0]}, '
                        f'{self.limits[1]}]')
        if self.choices and value not in self.choices:
            return f'{self.name} = {value!r} is not one of {", ".join(self.choices)}'
        if self.limits is not None and isinstance(value, list | tuple):
            low, high = self.limits
            bad = [item for item in value if not low <= item <= high]
            if bad:
                return f'{self.name} has {bad} outside [{low}, {high}]'
        return None

    def value(self, parameter: Parameter) -> ParamValue:
        """The parameter's value in the default's type (an integer given for a float: float)."""
        return float(parameter.value) if self._is_float else parameter.value


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
