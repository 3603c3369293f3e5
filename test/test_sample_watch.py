"""Damaged samples counted as they arrive, wherever they fall (core.signal.sample_watch)."""

import numpy as np
import pytest

from fmm_ros.core.signal.sample_watch import SampleWatch

BATCH = 500


def fed(x, batch=BATCH, gaps=()):
    watch = SampleWatch()
    for first in range(0, x.size, batch):
        if first not in gaps:
            watch.watch('force', first, x[first : first + batch])
    return watch.damage['force']


@pytest.mark.parametrize('start', [30_000, 30_000 - 100, 30_000 - 499])  # across a batch edge
def test_nan_inf_and_a_stuck_run_in_a_noisy_channel_are_counted_once(start):
    x = np.random.default_rng(0).normal(0.0, 1.0, 100_000)
    x[start : start + 200] = x[start - 1]
    x[50_000:50_010] = np.nan
    x[60_000] = -np.inf
    damage = fed(x)
    assert (damage.nan_samples, damage.first_nan_index) == (10, 50_000)
    assert (damage.inf_samples, damage.first_inf_index) == (1, 60_000)
    assert (damage.stuck_runs, damage.stuck_samples) == (1, 201)
    assert damage.first_stuck_index == start - 1
    assert damage.summary('force') == (
        'force: 10 NaN from sample 50000, 1 infinite from sample 60000, '
        f'1 stuck run (201 samples) from sample {start - 1}'
    )


def test_a_short_repeat_in_noise_and_quiet_exact_zeros_without_noise_are_not_stuck():
    noisy = np.round(np.random.default_rng(1).normal(0.0, 3.0, 50_000))  # a coarse quantiser
    assert not fed(noisy).any
    quiet = np.zeros(100_000)
    quiet[1000:1100] = np.sin(np.arange(100.0))  # a noise-free simulation: a hit, then zeros
    assert not fed(quiet).any


def test_a_gap_ends_a_run():
    x = np.random.default_rng(2).normal(0.0, 1.0, 20_000)
    x[9_980:10_000] = 7.0  # 20 equal samples before a lost batch, 20 after it: not 40 in a row
    x[10_500:10_520] = 7.0
    assert fed(x, gaps={10_000}).stuck_runs == 0
    x[10_000:10_500] = 7.0  # without the gap they are one run of 540
    assert fed(x).stuck_runs == 1
