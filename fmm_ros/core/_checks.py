"""Argument checks shared by the core modules: each raises ValueError naming the argument."""

import math

import numpy as np


def require_finite(name: str, value: float) -> None:
    """A real, finite number (bools and strings are refused)."""
    if not isinstance(value, (int, float, np.integer, np.floating)) or isinstance(value, bool):
        raise ValueError(f'{name} must be a number, got {value!r}')
    if not math.isfinite(value):
        raise ValueError(f'{name} must be finite, got {value}')


def require_positive(name: str, value: float) -> None:
    """A finite number above zero."""
    require_finite(name, value)
    if value <= 0.0:
        raise ValueError(f'{name} must be positive, got {value}')


def require_non_negative(name: str, value: float) -> None:
    """A finite number not below zero."""
    require_finite(name, value)
    if value < 0.0:
        raise ValueError(f'{name} must not be negative, got {value}')
