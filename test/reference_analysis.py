"""The per-record analysis steps as numpy defines them, before they were made faster (issue 28).

Each faster step of a record's analysis (`quality.mad_std`, `frf.median_in_place`, ...) has
its definition here: the numpy expression it replaced. `use_numpy_steps` swaps every one
for its definition, so a test can analyse the same records both ways and hold the results
equal to the bit.
"""

import numpy as np
import pytest

from fmm_ros.core.signal import frf, quality


def median(values: np.ndarray) -> float:
    """np.median, as the noise estimates took it."""
    return float(np.median(values))


def mad_deviation(values: np.ndarray) -> float:
    """The MAD deviation of the finite values, as `robust_center_and_std` takes it."""
    return quality._center_and_std(values)[1]


NUMPY_STEPS = {
    (frf, 'median_in_place'): median,
    (quality, 'mad_std'): mad_deviation,
}
"""(module, name) of each faster step -> its numpy definition."""


def use_numpy_steps(monkeypatch: pytest.MonkeyPatch) -> None:
    """Run every faster step as its numpy definition until the test ends."""
    for (module, name), definition in NUMPY_STEPS.items():
        monkeypatch.setattr(module, name, definition)
