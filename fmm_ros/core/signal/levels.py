"""Force levels: which nominal level a hit's peak force belongs to, or clusters without any.

Plain functions on arrays, as `frf`: `assign_nominal_levels` (the paper's +-50 N rule around
450/1000/1450 N) and `cluster_levels` (levels found from the peak forces alone).
"""

from __future__ import annotations

import numpy as np


def assign_nominal_levels(
    peak_force_n: np.ndarray, nominal_peak_force_n: np.ndarray, tolerance_n: np.ndarray | float
) -> np.ndarray:
    """Index of the nearest nominal level within its tolerance for each peak force, else -1.

    The paper accepted impacts within +-50 N of the nominal 450/1000/1450 N (Sec. 4).
    """
    peaks = np.asarray(peak_force_n, dtype=float)[:, None]
    nominal = np.asarray(nominal_peak_force_n, dtype=float)[None, :]
    if nominal.size == 0:
        return np.full(peaks.shape[0], -1)
    distance = np.abs(peaks - nominal)
    inside = distance <= np.broadcast_to(np.asarray(tolerance_n, dtype=float), nominal.shape)
    distance = np.where(inside, distance, np.inf)
    nearest = np.argmin(distance, axis=1)
    return np.where(np.isfinite(distance[np.arange(peaks.shape[0]), nearest]), nearest, -1)


def cluster_levels(peak_force_n: np.ndarray, relative_gap: float = 0.15) -> np.ndarray:
    """Group peak forces into levels when no nominal levels are given: labels 0, 1, ... by force.

    Sorted peak forces are split wherever two neighbours differ by more than `relative_gap`
    times the larger one (single-linkage clustering in one dimension: deterministic, no level
    count to guess). Hand-held hammer levels spread by a few percent and sit tens of percent
    apart, so the default of 15 % separates 450/1000/1450 N while keeping each level whole.
    Non-finite forces get -1.
    """
    peaks = np.asarray(peak_force_n, dtype=float)
    labels = np.full(peaks.size, -1)
    finite = np.flatnonzero(np.isfinite(peaks))
    if finite.size == 0:
        return labels
    order = finite[np.argsort(peaks[finite], kind='stable')]
    sorted_peaks = peaks[order]
    upper = np.maximum(np.abs(sorted_peaks[1:]), np.abs(sorted_peaks[:-1]))
    breaks = np.diff(sorted_peaks) > relative_gap * upper
    labels[order] = np.concatenate(([0], np.cumsum(breaks)))
    return labels
