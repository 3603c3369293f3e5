"""The one table of units a lab's DAQ or file may state, and their conversion to SI.

Every path that takes numbers with a unit (lab files, live SampleBatch messages, bags on
replay) converts through `si_factor`, so a unit is known everywhere or nowhere, and anything
else is refused by name (`UnitError`) instead of being read as if it were SI.
"""

from __future__ import annotations

import math

from fmm_ros.errors import UnitError

STANDARD_GRAVITY_M_S2 = 9.80665

# SI value of one unit of each kind; lookups ignore case and surrounding blanks ("MM/S" is mm/s).
FORCE_UNITS = {
    'N': 1.0,
    'kN': 1e3,
    'mN': 1e-3,
    'lbf': 4.4482216152605,
    'kgf': STANDARD_GRAVITY_M_S2,
}
VELOCITY_UNITS = {
    'm/s': 1.0,
    'cm/s': 1e-2,
    'mm/s': 1e-3,
    'um/s': 1e-6,
    'µm/s': 1e-6,
    'in/s': 0.0254,
    'ft/s': 0.3048,
}
ACCELERATION_UNITS = {
    'm/s^2': 1.0,
    'm/s2': 1.0,
    'm/s²': 1.0,
    'mm/s^2': 1e-3,
    'mm/s2': 1e-3,
    'g': STANDARD_GRAVITY_M_S2,
    'in/s^2': 0.0254,
    'ft/s^2': 0.3048,
}
DISPLACEMENT_UNITS = {
    'm': 1.0,
    'cm': 1e-2,
    'mm': 1e-3,
    'um': 1e-6,
    'µm': 1e-6,
    'nm': 1e-9,
    'in': 0.0254,
    'mil': 2.54e-5,
}
TIME_UNITS = {'s': 1.0, 'ms': 1e-3, 'us': 1e-6, 'µs': 1e-6}

QUANTITY_UNITS = {
    'force': FORCE_UNITS,
    'velocity': VELOCITY_UNITS,
    'acceleration': ACCELERATION_UNITS,
    'displacement': DISPLACEMENT_UNITS,
    'time': TIME_UNITS,
}
"""Each quantity's units, the first being its SI unit."""
SI_UNITS = {quantity: next(iter(units)) for quantity, units in QUANTITY_UNITS.items()}

SENSOR_UNITS = {'V': 1.0, 'mV': 1e-3}
"""Units of an uncalibrated channel (a voltage), in volts. Without a scale such a channel is
analysed in volts and every figure derived from it is per V; with a scale (SI units per one
file unit, N/V for a force) it becomes SI."""


def lookup_unit(quantity: str, unit: str | None) -> tuple[str, float] | None:
    """(canonical name, SI factor) of `unit` as a `quantity` unit, ignoring case, or None."""
    if not unit:
        return None
    wanted = unit.strip().lower()
    for name, value in _units_of(quantity).items():
        if name.lower() == wanted:
            return name, value
    return None


def quantity_of_unit(unit: str | None, besides: str) -> str | None:
    """The quantity other than `besides` that `unit` is a unit of, or None (for hints)."""
    return next(
        (kind for kind in QUANTITY_UNITS if kind != besides and lookup_unit(kind, unit)), None
    )


def si_factor(quantity: str, unit: str) -> float:
    """SI units per one `unit` of `quantity` (1000.0 for force in kN); UnitError if unknown."""
    known = lookup_unit(quantity, unit)
    if known is None:
        other = quantity_of_unit(unit, quantity)
        hint = f' ({unit!r} is a {other} unit)' if other else ''
        raise UnitError(
            f'{quantity} in unit {unit!r} cannot be converted to SI{hint}; '
            f'known {quantity} units: {", ".join(_units_of(quantity))}'
        )
    return known[1]


def channel_factor(
    quantity: str, unit: str | None, scale: float | None = None, *, channel: str = ''
) -> tuple[float, str]:
    """Factor from a channel's file numbers to the unit the analysis uses, and that unit.

    The one rule every command applies to a channel's unit and scale:

    - a unit of the table (kN, mm, g), no scale: to SI (1000.0, 'N' for kN);
    - a stated scale, with no unit or a unit the table does not know (V, counts): scale is SI
      units per file unit (35.15 N/V), so the channel is SI ((35.15, 'N'));
    - a sensor unit (V, mV) without a scale: analysed in volts ((1e-3, 'V') for mV);
    - no unit and no scale: the numbers are SI already.

    A scale beside a unit of the table, an unknown unit without a scale, or a scale that is not
    a finite non-zero number is refused (UnitError) naming the channel.
    """
    _units_of(quantity)
    si = SI_UNITS[quantity]
    label = f'{quantity} {channel!r}' if channel else quantity
    known = lookup_unit(quantity, unit)
    if scale is not None:
        if not (math.isfinite(scale) and scale != 0.0):
            raise UnitError(f'{label}: scale must be a finite non-zero number, got {scale!r}')
        if known is not None:
            raise UnitError(
                f'{label}: unit {unit} already fixes the scale ({known[1]:g} {si} per '
                f'{unit}); drop the scale, or give the raw sensor unit (e.g. V) with the scale '
                f'in {si} per that unit'
            )
        return float(scale), si
    if known is not None:
        return known[1], si
    if not unit or not unit.strip():
        return 1.0, si
    sensor = next((name for name in SENSOR_UNITS if name.lower() == unit.strip().lower()), None)
    if sensor is not None:
        return SENSOR_UNITS[sensor], 'V'
    try:
        return si_factor(quantity, unit), si
    except UnitError as error:
        raise UnitError(
            f'{label}: {error}, or a sensor unit ({", ".join(SENSOR_UNITS)}); for another '
            f'sensor unit give a scale in {si} per {unit}'
        ) from None


def per_unit(force_unit: str, displacement_unit: str, seconds: int = 0) -> str:
    """The unit of a force per displacement times s^seconds: 'N/m', 'N s/m', 'V s^2/V'.

    Parameters of a model keep their SI names; this says what their numbers are in when a
    channel was analysed in its own units (a voltage).
    """
    time = {0: '', 1: ' s', 2: ' s^2'}.get(seconds, f' s^{seconds}')
    return f'{force_unit}{time}/{displacement_unit}'


def sample_si_factor(quantity: str, unit: str) -> float:
    """SI factor of a sample channel's stated unit (SampleBatch.unit); '' means SI.

    The live nodes and replay convert every batch through this, once, at their input.
    """
    return si_factor(quantity, unit) if unit.strip() else 1.0


def _units_of(quantity: str) -> dict[str, float]:
    try:
        return QUANTITY_UNITS[quantity]
    except KeyError:
        raise UnitError(
            f'unknown quantity {quantity!r}; known: {", ".join(QUANTITY_UNITS)}'
        ) from None
