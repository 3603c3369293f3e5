"""One declaration per setting: a dataclass field that carries its unit, help and limits.

The settings of the core (capture, analysis, the rig, a fit) are frozen dataclasses whose
fields are made by `setting`. Everything that shows or takes a setting reads it from there
through `settings_of`: the ROS parameter tables (`fmm_ros.ros.params.params_from`), the `fmm`
options (`fmm_ros.cli.options.add_settings`) and the reference pages of the docs. A default,
unit, range or help text is therefore written once.

This module imports the standard library only, so `fmm --help` (which shows every default)
does not pay for numpy. The scalar checks the settings' `__post_init__` use live here too;
they raise `BadInputError` (a ValueError) naming the setting.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass
from typing import Any

from fmm_ros.errors import BadInputError

_KEY = 'fmm_setting'


@dataclass(frozen=True)
class Setting:
    """What a settings field declares: name, default, unit, help, limits, choices, flag."""

    name: str
    default: Any
    unit: str
    help: str
    limits: tuple[float, float] | None = None
    choices: tuple[str, ...] = ()
    # The `fmm` option's spelling where it is not the field name with dashes (`--trigger-n`).
    flag: str = ''

    @property
    def option(self) -> str:
        """The `fmm` option: `--window-s` for `window_s`, unless the field names another."""
        return self.flag or '--' + self.name.replace('_', '-')

    @property
    def described(self) -> str:
        """The help with its unit in brackets: 'Record length [s]'."""
        return f'{self.help} [{self.unit}]' if self.unit else self.help


def setting(
    default: Any,
    *,
    help: str,
    unit: str = '',
    limits: tuple[float, float] | None = None,
    choices: tuple[str, ...] = (),
    flag: str = '',
) -> Any:
    """A dataclass field with a default that carries its unit, help, limits and choices.

    unit: the SI unit ('' for a flag, a name or a count); limits: the inclusive range a number
    (or each element of a tuple of numbers) must lie in; flag: the `fmm` option if not the
    field name with dashes.
    """
    meta = {'unit': unit, 'help': help, 'limits': limits, 'choices': choices, 'flag': flag}
    return dataclasses.field(default=default, metadata={_KEY: meta})


def settings_of(cls_or_instance: Any) -> tuple[Setting, ...]:
    """The declared settings of a settings dataclass, in field order (with its defaults).

    Given an instance, `default` is that instance's value.
    """
    instance = None if isinstance(cls_or_instance, type) else cls_or_instance
    return tuple(
        Setting(
            name=field.name,
            default=field.default if instance is None else getattr(instance, field.name),
            **field.metadata[_KEY],
        )
        for field in dataclasses.fields(cls_or_instance)
        if _KEY in field.metadata
    )


def setting_of(cls: type, name: str) -> Setting:
    """One declared setting of cls by field name (KeyError if it declares none)."""
    for item in settings_of(cls):
        if item.name == name:
            return item
    raise KeyError(f'{cls.__name__} declares no setting {name!r}')


def setting_like(cls: type, name: str) -> Any:
    """A field declared as cls's setting name is: the same default, unit, help and limits.

    For a settings class that carries another's settings (the capture carries the stream's
    tolerances), so they are declared once.
    """
    item = setting_of(cls, name)
    return setting(
        item.default,
        help=item.help,
        unit=item.unit,
        limits=item.limits,
        choices=item.choices,
        flag=item.flag,
    )


# -- scalar checks (numpy-free: numpy registers its scalars with `numbers`) ---------------------


def require_finite(name: str, value: float) -> None:
    """A real, finite number (bools and strings are refused)."""
    if not isinstance(value, numbers.Real) or isinstance(value, bool):
        raise BadInputError(f'{name} must be a number, got {value!r}')
    if not math.isfinite(value):
        raise BadInputError(f'{name} must be finite, got {value}')


def require_positive(name: str, value: float) -> None:
    """A finite number above zero."""
    require_finite(name, value)
    if value <= 0.0:
        raise BadInputError(f'{name} must be positive, got {value}')


def require_non_negative(name: str, value: float) -> None:
    """A finite number not below zero."""
    require_finite(name, value)
    if value < 0.0:
        raise BadInputError(f'{name} must not be negative, got {value}')
