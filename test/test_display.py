"""Channels decimated for live plots: peaks kept, intervals on the sample index, gaps closed."""

import numpy as np
import pytest

from fmm_ros.core.signal.display import PeakDecimator, samples_per_point
from fmm_ros.errors import BadInputError


def _feed_all(decimator, signal, batch):
    points = []
    for first in range(0, signal.size, batch):
        points += decimator.feed(first, signal[first : first + batch])
    return points + decimator.flush()


@pytest.mark.parametrize('batch', [1, 37, 200, 500, 1000])
def test_a_one_sample_pulse_keeps_its_height_and_sign_whatever_the_batches(batch):
    signal = np.random.default_rng(0).normal(0.0, 0.2, 10_000)
    signal[4321] = -950.0
    points = _feed_all(PeakDecimator(200), signal, batch)
    assert [p.first_sample_index for p in points] == list(range(0, 10_000, 200))
    assert all(p.sample_count == 200 for p in points)
    hit = points[4321 // 200]
    assert hit.value == -950.0 == hit.minimum and hit.maximum == signal[4200:4400].max()
    quiet = np.array([p.value for i, p in enumerate(points) if i != 4321 // 200])
    assert np.all(np.abs(quiet) < 1.5)


def test_intervals_sit_on_the_index_so_two_channels_line_up():
    decimator = PeakDecimator(100)
    points = decimator.feed(250, np.arange(400.0))  # samples 250..649
    assert [(p.first_sample_index, p.sample_count) for p in points] == [
        (200, 50),
        (300, 100),
        (400, 100),
        (500, 100),
    ]
    (last,) = decimator.flush()
    assert (last.first_sample_index, last.sample_count, last.value) == (600, 50, 399.0)


def test_a_gap_closes_the_open_interval_and_missing_samples_are_left_out():
    decimator = PeakDecimator(100)
    (first,) = decimator.feed(0, np.full(150, 2.0))
    assert (first.first_sample_index, first.sample_count, first.value) == (0, 100, 2.0)
    points = decimator.feed(400, np.concatenate([np.full(100, np.nan), np.full(100, -3.0)]))
    assert [(p.first_sample_index, p.sample_count, p.value) for p in points] == [
        (100, 50, 2.0),
        (500, 100, -3.0),
    ]


def test_bad_settings_and_shapes_are_refused_with_the_reason():
    with pytest.raises(BadInputError, match='at least 1 sample'):
        PeakDecimator(0)
    with pytest.raises(BadInputError, match='one-dimensional'):
        PeakDecimator(10).feed(0, np.zeros((2, 5)))
    assert samples_per_point(10_000.0, 50.0) == 200
    assert samples_per_point(100.0, 1000.0) == 1
