"""The faster per-record analysis steps give their numpy definitions' numbers.

Each step made faster for replay (`reference_analysis.NUMPY_STEPS`) is held two ways: alone,
against its numpy definition on arrays with ties, signed zeros, NaN and the sizes at its
edges (empty, one value, even and odd counts, constant); and in place, by analysing the same
records with every step swapped back for its definition and holding every field of every
result equal to the bit. The records are the damaged-hit matrix (every fault family, so every
flag's path), lab-chain records from the held-out generator (filtered, quantised, offset,
hum), and short and constant records.
"""

import dataclasses
import math

import numpy as np
import pytest
import reference_analysis
from damaged_records import FAULTS, session
from heldout.lab import EVENTS, Effects
from heldout.lab import session as lab_session
from reference_analysis import mad_deviation, numpy_steps

from fmm_ros.core.signal import _kernels, frf, quality
from fmm_ros.core.signal.analysis import analyze_impact
from fmm_ros.core.signal.records import ImpactRecord


def awkward_arrays():
    """Arrays that test a median's edges: sizes 1-9 and long, ties, signed zeros, extremes."""
    rng = np.random.default_rng(28)
    arrays = [np.zeros(1), np.full(7, 3.5), np.array([-0.0, 0.0]), np.array([0.0, -0.0, 0.0])]
    for size in (*range(1, 10), 40_000, 41_251, 165_000):
        arrays.append(rng.normal(0.0, 1.0, size))
        arrays.append(rng.normal(0.0, 0.2, size).round(2))  # many ties
        arrays.append(rng.choice([-0.0, 0.0, 1.0, -1.0, 5e-324, 1e300, -1e300], size))
    return arrays


def test_median_in_place_is_numpys_median():
    """The same value (a zero's sign may differ: no |value - median| tells it apart)."""
    for values in awkward_arrays():
        assert frf.median_in_place(values.copy()) == np.median(values), values.size


def test_mad_std_is_robust_center_and_stds_deviation_to_the_bit():
    for values in awkward_arrays():
        for corrupt in (None, np.nan, np.inf):
            values = values.copy()
            if corrupt is not None:
                values[:: max(values.size // 3, 2)] = corrupt
            np.testing.assert_equal(quality.mad_std(values.copy()), mad_deviation(values))
    assert math.isnan(quality.mad_std(np.array([np.nan, np.inf])))
    assert math.isnan(quality.mad_std(np.zeros(0)))


@pytest.mark.slow  # the first call compiles the kernel (cold cache: ~1 s)
def test_equal_runs_are_the_runs_of_numpys_equal_mask():
    rng = np.random.default_rng(29)
    cases = [np.zeros(0), np.zeros(1), np.zeros(2), np.array([1.0, np.nan, np.nan])]
    cases += [np.full(30, np.inf), np.full(30, 0.25), np.array([-0.0, 0.0] * 20)]
    for size in (24, 25, 26, 1000, 330_000):
        values = rng.normal(0.0, 1.0, size).round(1)  # short runs by chance
        for _ in range(4):  # held stretches, at the ends too
            at, length = int(rng.integers(0, size)), int(rng.integers(1, 60))
            values[max(at - length, 0) : at] = rng.choice([0.0, values[at - 1], np.nan, np.inf])
        values[:25] = values[0]
        cases.append(values)
    for values in cases:
        for min_length in (0, 1, 24):
            ours = _kernels.equal_runs(values, min_length)
            theirs = reference_analysis.equal_runs(values, min_length)
            assert ours[0] == theirs[0]
            np.testing.assert_array_equal(ours[1], theirs[1])
            np.testing.assert_array_equal(ours[2], theirs[2])


@pytest.mark.slow  # the first call compiles the kernel (cold cache: ~1 s)
def test_reversals_are_numpys_reversals_to_the_bit():
    rng = np.random.default_rng(30)
    t = np.arange(20_000) / 5000.0
    decay = np.sin(2 * np.pi * 2.2 * t) * np.maximum(0.0, 0.3 - 0.05 * t)
    cases = [np.zeros(3), np.full(100, 1.0), np.array([-0.0, 0.0, -1.0, 1.0, -0.0, 2.0, -2.0])]
    for noise in (0.0, 1e-4, 3e-3):
        noisy = decay + rng.normal(0.0, noise, t.size)
        noisy[rng.integers(0, t.size, 50)] = rng.choice([0.0, -0.0])  # signed zeros
        cases.append(noisy)
    cases.append(rng.choice([-1.0, -0.0, 0.0, 1.0, 1e-300], 5000))
    for smooth in cases:
        for hysteresis in (0.0, 1e-3, 0.05, 2.0):
            ours = _kernels.reversals(smooth, hysteresis)
            with np.errstate(invalid='ignore'):  # 0 / 0 between -0.0 and 0.0
                theirs = reference_analysis.reversals(smooth, hysteresis)
            for mine, numpys in zip(ours, theirs, strict=True):
                np.testing.assert_array_equal(mine, numpys)
                np.testing.assert_array_equal(np.signbit(mine), np.signbit(numpys))


def records():
    """Records of every fault family, of a held-out lab chain, and the edges: short, constant."""
    out = [hit.record for fault in ('', *FAULTS) for hit in session(fault, seed=28)[0]]
    rng = np.random.default_rng(28)
    out += [
        ImpactRecord(record.force_n, record.velocity_m_s, record.sample_rate_hz)
        for record in lab_session(EVENTS, Effects(), 0.113, rng)
    ]
    first, peak = out[0], int(np.argmax(out[0].force_n))
    short = slice(peak - 40, peak + 60)
    out.append(
        dataclasses.replace(
            first, force_n=first.force_n[short], velocity_m_s=first.velocity_m_s[short]
        )
    )
    out.append(dataclasses.replace(first, velocity_m_s=np.full(first.force_n.size, 2e-3)))
    return out


def assert_same(ours, theirs):
    """Every field of two ImpactAnalysis equal to the bit (NaN equal to NaN)."""
    for field in dataclasses.fields(ours):
        a, b = getattr(ours, field.name), getattr(theirs, field.name)
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b, err_msg=field.name)
        else:
            np.testing.assert_equal(a, b, err_msg=field.name)


@pytest.mark.slow
def test_analysis_with_the_faster_steps_is_the_analysis_with_their_definitions():
    cases = records()
    fast = [analyze_impact(record, impact_id=k) for k, record in enumerate(cases)]
    assert {flag for result in fast for flag in result.flags} >= {
        'clipped',
        'double_hit',
        'saturated',
        'no_response',
        'dropout',
        'nan',
    }
    with numpy_steps():
        before = [analyze_impact(record, impact_id=k) for k, record in enumerate(cases)]
    for ours, theirs in zip(fast, before, strict=True):
        assert_same(ours, theirs)
    assert quality.mad_std is not mad_deviation  # restored
