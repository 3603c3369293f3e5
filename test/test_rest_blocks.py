"""The exact solver's stretches at rest, filled a block at a time, change no number.

A record is mostly rest, which the kernel now tests 64 samples at a time. Fed in batches of
a few samples the same stream never holds a whole block, so every sample takes the
one-at-a-time rule: the two must agree bit for bit, whatever the model and however the rest
stretches fall against the blocks.
"""

import numpy as np
import pytest

from fmm_ros.core.physics._kernels import REST_BLOCK
from fmm_ros.core.physics.model import OscillatorStream, simulate
from fmm_ros.core.physics.terms import model_term
from fmm_ros.sim.excitation import impact_record

RATE_HZ = 10_000.0


@pytest.mark.slow
@pytest.mark.parametrize(
    'effects', [(), ('stribeck',), ('asymmetric_friction', 'velocity_offset', 'sensor_delay')]
)
@pytest.mark.parametrize('seed', [1, 2])
def test_whole_record_equals_few_samples_at_a_time(effects, seed):
    terms = tuple(model_term(name) for name in effects)
    force = impact_record(1000.0, rng=seed, duration_s=4.0).force_n
    # A second hit while the first is at rest, at a sample no block boundary falls on.
    force = force + np.roll(force, 12_345)
    whole = simulate(force, RATE_HZ, effects=terms)
    stream = OscillatorStream(RATE_HZ, effects=terms)
    pieces = [
        np.array(stream.step(force[start : start + 7]), copy=True)
        for start in range(0, force.size, 7)
    ]
    displacement, velocity = np.concatenate(pieces, axis=1)
    np.testing.assert_array_equal(whole.displacement_m, displacement)
    np.testing.assert_array_equal(whole.velocity_m_s, velocity)
    resting = np.count_nonzero(np.diff(displacement) == 0.0)
    assert 10 * REST_BLOCK < resting < force.size  # both motion and rests of many blocks
