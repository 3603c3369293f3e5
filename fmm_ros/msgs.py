"""numpy <-> fmm_interfaces message conversion: the only module that knows field layouts.

Large float64[] fields go in through `array.array('d', x.tobytes())` (one memcpy, no Python
floats) and come out through `np.frombuffer` (no copy at all), as the brief measured that
Python lists cost orders of magnitude more.
"""

import array

import numpy as np
from builtin_interfaces.msg import Time

from fmm_interfaces.msg import SampleBatch

FORCE = ('force', 'N')
VELOCITY = ('velocity', 'm/s')


def float64_field(values: np.ndarray) -> array.array:
    """A float64[] message field holding a copy of values."""
    return array.array('d', np.ascontiguousarray(values, dtype=np.float64).tobytes())


def field_array(field: array.array) -> np.ndarray:
    """A read-only float64 view of a float64[] message field, without copying."""
    view = np.frombuffer(field, dtype=np.float64)
    view.flags.writeable = False
    return view


def sample_batch(samples: np.ndarray, *, quantity: tuple[str, str], sample_rate_hz: float,
                 first_sample_index: int, stamp: Time, frame_id: str,
                 full_scale: float = 0.0) -> SampleBatch:
    """A SampleBatch message; quantity is FORCE or VELOCITY (name and SI unit)."""
    msg = SampleBatch()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.quantity, msg.unit = quantity
    msg.sample_rate_hz = float(sample_rate_hz)
    msg.first_sample_index = int(first_sample_index)
    msg.full_scale = float(full_scale)
    msg.samples = float64_field(samples)
    return msg
