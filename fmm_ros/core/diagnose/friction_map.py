"""The friction law the records show, without a model of it: mu against sliding speed and position.

The friction force is what the rest of the equation of motion leaves over,

    F_f sgn(x') = f - m x'' - c x' - k x - k3 x^3,

with x integrated from the measured velocity (from each hit's fitted start) and x'' never
formed sample by sample: differentiating 1e-4 m/s of white noise at 10 kHz gives 14 N of
noise in m x'', twenty times the friction force. Instead the equation is integrated over
short runs [a, b] in which the sliding direction s and the bin (of speed, or of position) stay
the same:

    mean mu over the run = s (int f dt - m (v_b - v_a) - c (x_b - x_a) - k int x dt
                              - k3 int x^3 dt) / (N (t_b - t_a)),

which is exact (the friction averaged over the run), needs the velocity only at the run's
two ends (each a local mean of ENDPOINT_SAMPLES raw samples, too short to blur the kink at a
reversal) and integrals, where the noise averages out. The direction and the bins come from
the velocity low-passed at CLASSIFY_BAND_FN x f_n (zero phase); samples slower than the
noise floor of that signal, and the hit itself, are left out.

A bin's mu is the time-weighted mean of its runs (the time-average friction in the bin); its
standard error is the larger of the runs' scatter about it (a cluster-robust error: each run
one independent cluster, real variation inside the bin included) and the endpoint noise
propagated (the floor when runs are few and alike). Bins with fewer than MIN_RUNS runs are
left out. The rig's m, c, k (and any fitted cubic stiffness) are taken as given: an error
in them shows in the map (k x as a trend with position, m x'' near the reversals, where the
speed is lowest).
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fmm_ros._lazy import LazyModule
from fmm_ros.core.physics.rig import Rig

signal = LazyModule('scipy.signal')

CLASSIFY_BAND_FN = 50.0
"""The velocity that sorts samples into directions and bins is low-passed at this many f_n."""


ENDPOINT_SAMPLES = 7
"""The velocity at a run's end is the mean of this many raw samples centred there."""


MIN_RUN_SAMPLES = 10
"""Shorter runs are left out (their endpoint noise swamps their friction)."""


MIN_RUNS = 5
"""A bin needs this many runs for a mean and a scatter."""


SPEED_BINS = 12
POSITION_BINS = 12


FLOOR_SIGMAS = 20.0
"""Samples slower than this many noise deviations of the low-passed velocity are left out."""


HIT_GUARD_S = 2e-3
"""Left out after the hit's gate: its ringing is the hit's, not the contact's."""


@dataclass(frozen=True)
class FrictionCurve:
    """mu binned against one variable: bin centres, mu, its standard error, the runs behind."""

    centres: tuple[float, ...]
    """Time-weighted mean of the variable over each bin's runs (m/s or m)."""
    mu: tuple[float, ...]
    mu_stderr: tuple[float, ...]
    runs: tuple[int, ...]


@dataclass(frozen=True)
class FrictionMap:
    """mu against sliding speed and against position, over every record of a session."""

    speed: FrictionCurve
    position: FrictionCurve


@dataclass(frozen=True)
class MapRecord:
    """One record as the map takes it: its force, its velocity cleared of non-friction terms.

    velocity_m_s is the measured velocity less what the fitted model attributes to the sensor
    or the structure (an offset, a second mode), so that it is the friction oscillator's own.
    """

    force_n: np.ndarray
    velocity_m_s: np.ndarray
    start_position_m: float
    first_sample: int
    """First sample after the hit (its gate and HIT_GUARD_S)."""


@dataclass(frozen=True)
class _Prepared:
    """One record sorted for the map: its displacement, smoothed speed, sliding direction."""

    record: MapRecord
    displacement_m: np.ndarray
    speed_m_s: np.ndarray
    direction: np.ndarray
    """+1 / -1 where the record slides (after the hit, above the floor), 0 elsewhere."""
    floor_m_s: float


def friction_map(
    records: Sequence[MapRecord],
    sample_rate_hz: float,
    noise_std_m_s: float,
    rig: Rig,
    cubic_stiffness_n_per_m3: float = 0.0,
) -> FrictionMap:
    """The map of mu against speed and position over the records (module doc)."""
    prepared = [_prepare(record, sample_rate_hz, noise_std_m_s, rig) for record in records]
    sliding = [p.direction != 0.0 for p in prepared]
    if not any(np.any(s) for s in sliding):
        empty = FrictionCurve((), (), (), ())
        return FrictionMap(empty, empty)
    places = np.concatenate([p.displacement_m[s] for p, s in zip(prepared, sliding, strict=True)])
    low, high = np.percentile(places, [0.5, 99.5])
    position_edges = np.linspace(low, max(high, low + 1e-9), POSITION_BINS + 1)
    curves = []
    for edges, by_speed in ((_speed_edges(prepared), True), (position_edges, False)):
        runs = [
            _runs(p, edges, by_speed, sample_rate_hz, noise_std_m_s, rig, cubic_stiffness_n_per_m3)
            for p in prepared
        ]
        curves.append(_curve(runs, edges.size - 1))
    return FrictionMap(*curves)


def speed_table(
    records: Sequence[MapRecord],
    sample_rate_hz: float,
    noise_std_m_s: float,
    rig: Rig,
    cubic_stiffness_n_per_m3: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Each record's mu against speed, on speed bins the records share.

    Returns (mu, its standard error), a row a record and a column a speed bin of the records
    together (as `friction_map` bins them), NaN where a record has fewer than MIN_RUNS runs in
    a bin: so one bin is one speed range in every record, and the records' curves can be set
    side by side.
    """
    prepared = [_prepare(record, sample_rate_hz, noise_std_m_s, rig) for record in records]
    mu = np.full((len(prepared), SPEED_BINS), math.nan)
    error = np.full_like(mu, math.nan)
    if not any(np.any(p.direction != 0.0) for p in prepared):
        return mu, error
    edges = _speed_edges(prepared)
    for row, record in enumerate(prepared):
        runs = _runs(
            record, edges, True, sample_rate_hz, noise_std_m_s, rig, cubic_stiffness_n_per_m3
        )
        for column, _, mean, stderr, _ in _binned([runs], SPEED_BINS):
            mu[row, column], error[row, column] = mean, stderr
    return mu, error


def _speed_edges(prepared: Sequence[_Prepared]) -> np.ndarray:
    """Speed bin edges [m/s], log-spaced from the highest floor to the top sliding speed."""
    floor = max(p.floor_m_s for p in prepared)
    top = max(float(np.max(p.speed_m_s[p.direction != 0.0], initial=0.0)) for p in prepared)
    return np.geomspace(floor, max(top, 2.0 * floor), SPEED_BINS + 1)


def _prepare(record: MapRecord, rate: float, noise: float, rig: Rig) -> _Prepared:
    """Integrate the displacement, low-pass the speed, mark where and which way it slides."""
    velocity = record.velocity_m_s
    displacement = record.start_position_m + _running_integral(velocity, rate)
    cutoff = min(CLASSIFY_BAND_FN * rig.natural_frequency_hz, 0.4 * rate)
    sos = signal.butter(2, cutoff, fs=rate, output='sos')
    smooth = signal.sosfiltfilt(sos, velocity)
    # The low-pass keeps a bandwidth of about its cutoff of the white noise's rate / 2.
    floor = FLOOR_SIGMAS * noise * math.sqrt(2.0 * cutoff / rate)
    speed = np.abs(smooth)
    sliding = (np.arange(velocity.size) >= record.first_sample) & (speed > floor)
    direction = np.where(sliding, np.sign(smooth), 0.0)
    return _Prepared(record, displacement, speed, direction, floor)


def _running_integral(values: np.ndarray, rate: float) -> np.ndarray:
    """Trapezoid-rule integral from the first sample to each sample."""
    return np.concatenate(([0.0], np.cumsum(0.5 * (values[1:] + values[:-1])) / rate))


def _runs(
    prepared: _Prepared,
    edges: np.ndarray,
    by_speed: bool,
    rate: float,
    noise: float,
    rig: Rig,
    cubic: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(bin, duration, mean mu, its noise variance, mean variable) of each run of a record."""
    x = prepared.displacement_m
    variable = prepared.speed_m_s if by_speed else x
    bins = edges.size - 1
    index = np.searchsorted(edges, variable, side='right') - 1
    valid = (prepared.direction != 0.0) & (index >= 0) & (index < bins)
    key = np.where(valid, (index + 1) * prepared.direction, 0.0).astype(int)
    change = np.flatnonzero(np.diff(key)) + 1
    starts = np.concatenate(([0], change))
    stops = np.concatenate((change, [key.size])) - 1  # both ends inside the run
    half = ENDPOINT_SAMPLES // 2
    keep = (
        (key[starts] != 0)
        & (stops - starts + 1 >= MIN_RUN_SAMPLES)
        & (starts >= half)
        & (stops + half < key.size)
    )
    starts, stops = starts[keep], stops[keep]
    record = prepared.record
    local = np.convolve(record.velocity_m_s, np.ones(ENDPOINT_SAMPLES) / ENDPOINT_SAMPLES, 'same')
    impulse = _running_integral(record.force_n, rate)
    spring = rig.stiffness_n_per_m * _running_integral(x, rate)
    if cubic:
        spring += cubic * _running_integral(x**3, rate)
    duration = (stops - starts) / rate
    applied = impulse[stops] - impulse[starts]
    momentum = rig.mass_kg * (local[stops] - local[starts])
    viscous = rig.damping_n_s_per_m * (x[stops] - x[starts])
    restoring = spring[stops] - spring[starts]
    sign = np.sign(key[starts])
    mu = sign * (applied - momentum - viscous - restoring) / (rig.normal_force_n * duration)
    variance = 2.0 / ENDPOINT_SAMPLES * (rig.mass_kg * noise / (rig.normal_force_n * duration)) ** 2
    total = np.concatenate(([0.0], np.cumsum(variable)))
    mean_variable = (total[stops + 1] - total[starts]) / (stops - starts + 1)
    return np.abs(key[starts]) - 1, duration, mu, variance, mean_variable


def _curve(pieces, bins: int) -> FrictionCurve:
    """The curve of the bins with at least MIN_RUNS runs (`_binned`)."""
    binned = _binned(pieces, bins)
    return FrictionCurve(
        tuple(b[4] for b in binned),
        tuple(b[2] for b in binned),
        tuple(b[3] for b in binned),
        tuple(b[1] for b in binned),
    )


def _binned(pieces, bins: int) -> list[tuple[int, int, float, float, float]]:
    """(bin, runs, mu, its error, mean variable) of each bin with at least MIN_RUNS runs.

    mu is the bin's time-weighted mean over its runs; the error the larger of the
    cluster-robust scatter and the noise floor (module doc).
    """
    which = np.concatenate([p[0] for p in pieces])
    duration = np.concatenate([p[1] for p in pieces])
    mu = np.concatenate([p[2] for p in pieces])
    variance = np.concatenate([p[3] for p in pieces])
    variable = np.concatenate([p[4] for p in pieces])
    binned = []
    for b in range(bins):
        chosen = which == b
        count = int(np.count_nonzero(chosen))
        if count < MIN_RUNS:
            continue
        weight = duration[chosen]
        total = float(weight.sum())
        mean = float(weight @ mu[chosen]) / total
        scatter = math.sqrt(float(weight**2 @ (mu[chosen] - mean) ** 2) * count / (count - 1))
        floor = math.sqrt(float(weight**2 @ variance[chosen]))
        binned.append(
            (b, count, mean, max(scatter, floor) / total, float(weight @ variable[chosen]) / total)
        )
    return binned
