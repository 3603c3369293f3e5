"""One record made ready for an output-error fit: the force gated, the velocity left as measured.

Conditioning of the force (`condition_impact`), because the model integrates every sample it
is given: a 0.2 N noise floor over 33 s would drive the stuck mass into creep and bias mu.

- Baseline: the mean of the force outside the hit, subtracted.
- Gate: the hit is where the force departs from the baseline by more than
  `HIT_THRESHOLD_SIGMA` robust noise deviations (median absolute deviation); each such run
  of samples is widened by a quarter of its length (at least `GATE_MIN_MARGIN_S`) each side to
  take in the pulse's low-level edges, and the force is zeroed everywhere else. A bounce is a
  second run and is kept, as it drives the rig too.
- The velocity is left as measured: an offset or a lag in it is a model term the diagnosis
  must be able to see, not something conditioning may hide.
- No trigger index is used: the hit is found in the force itself, so a pre-trigger segment
  of any length and a trigger that fired some samples (or a fraction of one) after the hit
  began need no parameter; the model starts at rest at the first sample (at x = 0, or where
  `fit_initial_position` finds the previous hit left it). A lag of the velocity channel
  behind the force channel is the `sensor_delay` term, fitted on request.

Failures: bad input (shapes, non-finite samples, bad constants) is a BadInputError; a record
that friction cannot explain is a `FitError` whose `reason` is one of `FIT_FAILURES` (both in
`fmm_ros.errors`) and whose message says why, so the CLI and the fitter service can report it.
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from fmm_ros.core._checks import finite_samples, require_positive
from fmm_ros.core.signal.frf import impulse
from fmm_ros.core.signal.quality import robust_center_and_std, white_noise_std
from fmm_ros.errors import BadInputError, FitError

HIT_THRESHOLD_SIGMA = 10.0
"""A hit departs from the force baseline by more than this many noise deviations (Gaussian
noise reaches ~5 of them once in a 33 s record)."""


GATE_MARGIN_FRACTION = 0.25


GATE_MIN_MARGIN_S = 0.5e-3
"""Each run above the hit threshold is widened by this fraction of its length, and at least
this long, on both sides: the pulse's feet lie below the threshold."""


HIT_SETTLE_S = 1e-3
"""The velocity is not judged inside a gate and this long after it (see `hit_windows`)."""


MOTION_THRESHOLD_SIGMA = 10.0
"""The velocity must exceed this many noise deviations somewhere for a record to show motion."""


@dataclass(frozen=True, eq=False)
class ConditionedImpact:
    """One impact made ready for fitting: the force that drives the model, the velocity to match."""

    force_n: np.ndarray
    """Measured force minus its baseline inside the gate, zero outside [N]."""
    velocity_m_s: np.ndarray
    """Measured velocity, untouched [m/s]."""
    sample_rate_hz: float
    gate: tuple[tuple[int, int], ...]
    """[start, stop) sample ranges where the measured force is kept."""
    onset_index: int
    """First sample of the hit above the threshold (the rig is at rest before it)."""
    baseline_n: float
    force_noise_std_n: float
    """Robust (MAD) deviation of the force about its baseline [N]."""
    velocity_noise_std_m_s: float
    """White-noise level of the velocity channel, from its second differences [m/s]."""
    impulse_n_s: float
    """Trapezoid-rule impulse of the conditioned force [N*s]."""
    peak_force_n: float
    """Largest |conditioned force| [N]."""
    peak_velocity_m_s: float
    """Largest |measured velocity| [m/s]."""
    source: str = ''
    start_m: float = 0.0
    """Where the mass rests before the hit [m], when known: the model starts there unless the
    fit frees the start or chains it (0: the centre, as in the paper)."""
    follows_previous: bool = False
    """The hit found the rig where the hit before it in the same fit left it (a continuous
    session, nothing moving the rig between records): the model starts it where its own run
    of that hit came to rest (`OutputError.starts`)."""

    @property
    def hit_end_index(self) -> int:
        """First sample after the last gate: from here on no force acts."""
        return self.gate[-1][1]

    @property
    def hit_windows(self) -> tuple[tuple[int, int], ...]:
        """[start, stop) sample ranges where the fit does not judge the velocity.

        Each gate and `HIT_SETTLE_S` after it: while the hammer acts, the velocity follows
        the force's shape between its samples, which the samples do not pin down (a pulse
        rising in 0.2 ms is two samples at 10 kHz, one at 5 kHz), and anti-alias filters
        smear that shape for a few of their time constants more. The motion after it depends
        on the hit only through its impulse and timing, which the fit's impulse scale and
        start position take up. These few milliseconds carry nothing about friction.
        """
        settle = math.ceil(HIT_SETTLE_S * self.sample_rate_hz)
        n = self.velocity_m_s.size
        return tuple((start, min(stop + settle, n)) for start, stop in self.gate)

    @property
    def impulse_std_n_s(self) -> float:
        """Standard deviation the force noise gives the impulse that moves the rig [N*s].

        sigma_F / f_s times the root of the gated samples from the onset on: the noise in the
        gate's lead-in falls on a mass held by static friction (at 0.2 N it stays far below
        mu N), so it moves nothing.
        """
        samples = sum(stop - start for start, stop in self.gate) - (
            self.onset_index - self.gate[0][0]
        )
        return self.force_noise_std_n / self.sample_rate_hz * math.sqrt(samples)

    @property
    def duration_s(self) -> float:
        """Record length [s]."""
        return self.force_n.size / self.sample_rate_hz


def condition_impact(
    force_n: np.ndarray, velocity_m_s: np.ndarray, sample_rate_hz: float, *, source: str = ''
) -> ConditionedImpact:
    """Baseline-correct and gate a measured force; estimate both channels' noise.

    Raises BadInputError for malformed input and FitError ('no_hit', 'no_motion') for a force with
    no hit above its noise or a velocity with no response above its noise.
    """
    force = checked_channel('force_n', force_n, source)
    velocity = checked_channel('velocity_m_s', velocity_m_s, source)
    require_positive('sample_rate_hz', sample_rate_hz)
    if force.size != velocity.size:
        raise BadInputError(
            f'{source_prefix(source)}force has {force.size} samples but velocity has '
            f'{velocity.size}: the channels must be sample-aligned'
        )
    if force.size < 16:
        raise BadInputError(
            f'{source_prefix(source)}a record needs at least 16 samples, got {force.size}'
        )
    center, noise_n = robust_center_and_std(force)
    peak = max(float(force.max()) - center, center - float(force.min()))
    if peak <= HIT_THRESHOLD_SIGMA * noise_n or peak == 0.0:
        raise FitError(
            'no_hit',
            f'the force never departs from its baseline {center:.4g} N by '
            f'more than {HIT_THRESHOLD_SIGMA:g} noise deviations ({noise_n:.3g} N; '
            f'largest departure {peak:.3g} N): there is no hit to drive the model',
            source,
        )
    threshold = max(HIT_THRESHOLD_SIGMA * noise_n, 1e-3 * peak)
    hit = (force >= center + threshold) | (force <= center - threshold)
    gate = _gate(hit, sample_rate_hz)
    outside = np.ones(force.size, dtype=bool)
    for start, stop in gate:
        outside[start:stop] = False
    baseline = float(np.mean(force[outside])) if outside.any() else 0.0
    conditioned = np.zeros(force.size)
    for start, stop in gate:
        conditioned[start:stop] = force[start:stop] - baseline
    velocity_noise = velocity_noise_std(velocity)
    peak_velocity = float(np.max(np.abs(velocity)))
    if peak_velocity <= MOTION_THRESHOLD_SIGMA * velocity_noise or peak_velocity == 0.0:
        raise FitError(
            'no_motion',
            f'the velocity never exceeds {MOTION_THRESHOLD_SIGMA:g} '
            f'times its noise ({velocity_noise:.3g} m/s; peak {peak_velocity:.3g} '
            'm/s): the rig did not move',
            source,
        )
    return ConditionedImpact(
        force_n=conditioned,
        velocity_m_s=velocity,
        sample_rate_hz=float(sample_rate_hz),
        gate=gate,
        onset_index=int(np.argmax(hit)),
        baseline_n=baseline,
        force_noise_std_n=noise_n,
        velocity_noise_std_m_s=velocity_noise,
        impulse_n_s=impulse(conditioned, sample_rate_hz),
        peak_force_n=float(np.max(np.abs(conditioned))),
        peak_velocity_m_s=peak_velocity,
        source=source,
    )


def cropped_impact(impact: ConditionedImpact, stop_index: int) -> ConditionedImpact:
    """The impact's first stop_index samples, its noise levels, impulse and peaks kept as found.

    A record is at rest for most of its 33 s, and a fit's cost grows with its samples: the
    diagnosis fits the motion only. The noise estimates stay those of the whole record (more
    samples pin them better); the stop must lie after the hit's gate.
    """
    stop = int(stop_index)
    if not impact.hit_end_index <= stop <= impact.force_n.size:
        raise BadInputError(
            f'{source_prefix(impact.source)}cannot crop at sample {stop}: the hit ends at '
            f'{impact.hit_end_index} and the record has {impact.force_n.size} samples'
        )
    return replace(impact, force_n=impact.force_n[:stop], velocity_m_s=impact.velocity_m_s[:stop])


def velocity_noise_std(velocity_m_s: np.ndarray) -> float:
    """White-noise deviation of a velocity record [m/s], blind to the motion itself.

    The signal core's `white_noise_std` (MAD deviation of the second differences over sqrt(6)),
    the same estimate its quality flags judge a record by: the rig's few-Hz motion barely
    changes over two samples at 10 kHz, white noise does, and the median ignores the hit and
    the stops.
    """
    return white_noise_std(velocity_m_s)


def as_conditioned(impact) -> ConditionedImpact:
    """A ConditionedImpact as is, or any record with force_n, velocity_m_s, sample_rate_hz.

    Records (`fmm_ros.core.signal.ImpactRecord`, `fmm_ros.sim.excitation.SimulatedImpact`) are
    conditioned with `condition_impact`, their `source` (if any) naming them in errors.
    """
    if isinstance(impact, ConditionedImpact):
        return impact
    try:
        force, velocity, rate = impact.force_n, impact.velocity_m_s, impact.sample_rate_hz
    except AttributeError:
        raise BadInputError(
            f'an impact must have force_n, velocity_m_s and sample_rate_hz, got '
            f'{type(impact).__name__}'
        ) from None
    return condition_impact(force, velocity, rate, source=str(getattr(impact, 'source', '')))


def checked_channel(name: str, values: np.ndarray, source: str) -> np.ndarray:
    """Values as finite float samples, or ValueError naming the record and the bad sample."""
    try:
        return finite_samples(name, values)
    except ValueError as error:
        raise BadInputError(f'{source_prefix(source)}{error}') from None


def _gate(hit: np.ndarray, sample_rate_hz: float) -> tuple[tuple[int, int], ...]:
    """Runs of True, each widened by GATE_MARGIN_FRACTION of its length, overlaps merged."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], hit.view(np.int8), [0]))))
    minimum = max(1, math.ceil(GATE_MIN_MARGIN_S * sample_rate_hz))
    merged: list[list[int]] = []
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        margin = max(minimum, math.ceil(GATE_MARGIN_FRACTION * (stop - start)))
        start, stop = max(0, int(start) - margin), min(hit.size, int(stop) + margin)
        if merged and start <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], stop)
        else:
            merged.append([start, stop])
    return tuple((start, stop) for start, stop in merged)


def source_prefix(source: str) -> str:
    """'<source>: ' to start an error message about a named record ('' when unnamed)."""
    return f'{source}: ' if source else ''


def chained_starts(impacts: Sequence[ConditionedImpact]) -> list[ConditionedImpact]:
    """One continuous session's impacts (in hit order), each after the first chained.

    Each later impact `follows_previous`: its model starts where the model's run of the one
    before it came to rest.

    Why: with velocities alone, friction mu+ forward and mu- backward is exactly a symmetric
    contact with their mean and the spring's centre moved by (mu+ - mu-) N / (2 k) (with
    y = x + that shift the equation of motion and the stick rule are symmetric, and the
    velocities the same). A start fitted per hit takes the shift up, and so does a chain
    whose first start is fitted: the asymmetry shows only against one known position. So the
    first hit keeps its own `start_m` (the centre: a lab lifts the pin and lets the flexure
    centre the rig before the session's first hit), and each later one follows the model.
    """
    return [replace(impact, follows_previous=index > 0) for index, impact in enumerate(impacts)]
