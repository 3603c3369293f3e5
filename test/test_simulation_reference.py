"""The exact solver against the sample-by-sample rule, to the bit.

To run a record near memory speed the kernels fill a stretch at rest after one scan of its
force, step a sliding stretch in a loop of its own, test the force for bad samples as they
read it, and delay the vibrometer output in chunks. Here the same model is written one sample
at a time in plain Python, as the rule reads: stay at rest while the net force is inside the
band, one exact matrix step while sliding with no event in the interval, the event-located
interval (`_interval`, which the fast paths leave alone) otherwise; the second mode's steps;
the delay and offset as numpy expressions. Every record and model the benchmark times must
come out equal to the bit, as must every refusal of a bad force.
"""

import math

import numpy as np
import pytest

from fmm_ros.core.physics import _kernels as kernels
from fmm_ros.core.physics.model import INTEGRATORS, OscillatorStream, simulate
from fmm_ros.core.physics.terms import model_term
from fmm_ros.sim.excitation import impact_record

RATE_HZ = 10_000.0

MODELS = {
    'coulomb_viscous': (),
    'asymmetric': ('asymmetric_friction',),
    'second_mode': ('second_mode',),
    'offset_and_delay': ('velocity_offset', 'sensor_delay'),
    'all_terms': (
        'viscous_damping',
        'asymmetric_friction',
        'second_mode',
        'velocity_offset',
        'sensor_delay',
    ),
}


def _hit(peak_n: float, seed: int) -> np.ndarray:
    return impact_record(peak_n, rng=seed, duration_s=5.0).force_n


def _records() -> dict[str, np.ndarray]:
    """Hits at the paper's levels, a hit on a mass at rest mid-record, several hits."""
    single = _hit(1000.0, 1)
    return {
        'hit_450': _hit(450.0, 2),
        'hit_1000': single,
        'hit_1450': _hit(1450.0, 3),
        # the first hit has stuck by 2.95 s; the second lands at 3.4 s on the mass at rest
        'stick_then_hit': single + np.roll(_hit(450.0, 4), 33_345),
        # three hits, the later ones while the mass still moves
        'several_hits': single + np.roll(single, 3_001) + 0.5 * np.roll(single, 9_017),
    }


def _oscillator(force, stream):
    """The friction oscillator one sample at a time: (displacement, velocity)."""
    p = stream._params
    k = p[kernels.STIFFNESS]
    c = p[kernels.DAMPING]
    band_pos = p[kernels.FRICTION_POS]
    band_neg = -p[kernels.FRICTION_NEG]
    phi = p[kernels.PHI : kernels.PHI + 4]
    gamma_u0 = p[kernels.GAMMA_U0 : kernels.GAMMA_U0 + 2]
    gamma_du = p[kernels.GAMMA_DU : kernels.GAMMA_DU + 2]
    x, v = stream._state[kernels.STATE_X], stream._state[kernels.STATE_V]
    mode = 1 if v > 0.0 else -1 if v < 0.0 else kernels._break_direction(force[0] - k * x, p)
    rest_time = 0.0 if mode == 0 else math.nan
    displacement, velocity = np.empty(force.size), np.empty(force.size)
    displacement[0], velocity[0] = x, v
    for i in range(1, force.size):
        f0, f1 = force[i - 1], force[i]
        if mode == 0 and band_neg <= f1 - kernels._spring(x, p) <= band_pos:
            v = 0.0
        else:
            sliding = False
            if mode != 0:
                sigma = float(mode)
                u0 = f0 - sigma * (band_pos if mode > 0 else -band_neg)
                du = f1 - f0
                x1 = phi[0] * x + phi[1] * v + gamma_u0[0] * u0 + gamma_du[0] * du
                v1 = phi[2] * x + phi[3] * v + gamma_u0[1] * u0 + gamma_du[1] * du
                dip = sigma * (u0 - c * v - k * x) < 0.0 < sigma * (u0 + du - c * v1 - k * x1)
                sliding = sigma * v1 > 0.0 and not dip
            if sliding:
                x, v = x1, v1
            else:
                x, v, mode, rest_time, _, _ = kernels._interval(
                    x, v, mode, f0, f1, (i - 1) / RATE_HZ, rest_time, p, 0.0, math.nan
                )
        displacement[i], velocity[i] = x, v
    return displacement, velocity


def _second_mode(force, constants):
    """The second mode's exact steps, one sample at a time, from rest."""
    phi0, phi1, phi2, phi3, ga0, ga1, gb0, gb1 = constants[kernels.MODE_PHI :]
    x = v = 0.0
    displacement, velocity = np.zeros(force.size), np.zeros(force.size)
    for i in range(1, force.size):
        f0, du = force[i - 1], force[i] - force[i - 1]
        x, v = (
            phi0 * x + phi1 * v + ga0 * f0 + gb0 * du,
            phi2 * x + phi3 * v + ga1 * f0 + gb1 * du,
        )
        displacement[i], velocity[i] = x, v
    return displacement, velocity


def reference(force, effects, x0_m=0.0, v0_m_s=0.0):
    """The model's (displacement, velocity) as the rule reads, sample by sample."""
    stream = OscillatorStream(RATE_HZ, effects=effects, x0_m=x0_m, v0_m_s=v0_m_s)
    displacement, velocity = _oscillator(force, stream)
    if stream._mode is not None:
        second_x, second_v = _second_mode(force, stream._mode)
        displacement += second_x
        velocity += second_v
    if stream._delay_line is not None:  # the delay line starts full of the initial velocity
        fraction = stream._delay_fraction
        padded = np.concatenate((np.full(stream._delay_whole + 1, v0_m_s), velocity))
        velocity = (1.0 - fraction) * padded[1 : force.size + 1] + fraction * padded[: force.size]
    if stream._offset != 0.0:
        velocity = velocity + stream._offset
    return displacement, velocity


def _assert_bit_identical(got, expected, what):
    """Equal to the bit (a -0.0 for a 0.0 included), each array named if it differs."""
    for channel, a, b in zip(('displacement', 'velocity'), got, expected, strict=True):
        assert a.shape == b.shape
        assert np.array_equal(a.view(np.int64), b.view(np.int64)), f'{what}: {channel} differs'


@pytest.mark.slow
def test_the_records_hold_rests_of_many_blocks_and_motion():
    """Else the bulk rest and sliding paths would not be what the comparison below holds."""
    for name, force in _records().items():
        velocity = simulate(force, RATE_HZ).velocity_m_s
        resting = np.count_nonzero(velocity == 0.0)
        assert 10 * kernels.REST_BLOCK < resting < force.size - 5_000, name
    stuck = simulate(_records()['stick_then_hit'], RATE_HZ).velocity_m_s
    assert np.all(stuck[29_500:34_346] == 0.0) and np.all(stuck[34_346:34_400] != 0.0)


@pytest.mark.slow
@pytest.mark.parametrize('model', MODELS)
def test_every_timed_model_equals_the_sample_by_sample_rule(model):
    effects = tuple(model_term(name) for name in MODELS[model])
    for name, force in _records().items():
        expected = reference(force, effects)
        whole = simulate(force, RATE_HZ, effects=effects)
        _assert_bit_identical((whole.displacement_m, whole.velocity_m_s), expected, name)
        stream = OscillatorStream(RATE_HZ, effects=effects)
        pieces = [
            np.array(stream.step(force[a : a + 997]), copy=True) for a in range(0, force.size, 997)
        ]
        _assert_bit_identical(tuple(np.concatenate(pieces, axis=1)), expected, f'{name} in pieces')


@pytest.mark.slow
def test_a_start_in_motion_and_a_fractional_delay_equal_the_rule():
    effects = (model_term('second_mode'), model_term('sensor_delay', delay_s=2.37e-4))
    force = _hit(1000.0, 5)
    for x0_m, v0_m_s in ((2e-4, 0.0), (-1e-4, 3e-3), (0.0, -2e-3)):
        expected = reference(force, effects, x0_m, v0_m_s)
        got = simulate(force, RATE_HZ, effects=effects, x0_m=x0_m, v0_m_s=v0_m_s)
        _assert_bit_identical(
            (got.displacement_m, got.velocity_m_s), expected, f'x0 {x0_m}, v0 {v0_m_s}'
        )


@pytest.mark.parametrize('integrator', INTEGRATORS)
@pytest.mark.parametrize(
    ('where', 'value'),
    [(0, math.nan), (500, math.inf), (1_100, -math.inf), (5_000, math.nan), (-1, math.nan)],
)
def test_a_bad_sample_is_refused_and_named_wherever_it_falls(integrator, where, value):
    """At the first sample, at rest before the hit, during the motion, at rest after, last."""
    force = impact_record(1000.0, rng=6, duration_s=0.6, pretrigger_s=0.1).force_n
    force[where] = value
    index = where % force.size
    with pytest.raises(ValueError, match=f'force_n is not finite at sample {index} '):
        simulate(force, RATE_HZ, integrator=integrator)


def test_a_force_too_large_to_sum_is_refused_but_one_large_sample_is_not():
    with pytest.raises(ValueError, match='force_n is too large to integrate'):
        simulate(np.full(8, 1e308), RATE_HZ)
    force = np.zeros(330)
    force[100] = 1e306  # beyond the kernel's quick test, yet its sum is finite: simulated
    assert simulate(force, RATE_HZ).velocity_m_s.size == 330


def test_streams_of_one_model_share_a_read_only_plan_and_every_refusal_stays():
    """The checked constants are built once per model and rate (a fitter builds many streams)."""
    first, second = OscillatorStream(RATE_HZ, mu=1), OscillatorStream(RATE_HZ, mu=1)
    assert first._params is second._params and not first._params.flags.writeable
    with pytest.raises(ValueError, match='mu must be a number, got True'):
        OscillatorStream(RATE_HZ, mu=True)  # equal to the cached 1, yet refused
    with pytest.raises(ValueError, match='effects must be model terms'):
        OscillatorStream(RATE_HZ, effects=[['second_mode']])  # unhashable: refused uncached
    listed = OscillatorStream(RATE_HZ, effects=[model_term('second_mode')])
    assert listed._mode is not None
