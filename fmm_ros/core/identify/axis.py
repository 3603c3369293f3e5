"""Friction of a one-axis drive without a spring: inverse dynamics least squares (IDIM-LS).

A positioning axis (a ball-screw or linear-motor stage) has no flexure, runs in closed loop and
reports an encoder's position. Its drive force obeys

    F(t) = M a(t) + Fv v(t) + Fc sign(v(t)) + offset + k x(t),

with M the moving mass [kg], Fv viscous friction [N s/m], Fc Coulomb friction [N], offset a
constant force (gravity on an inclined axis, a force-sensor zero) and k a known spring
[N/m] (0 for a free axis). The model is linear in (M, Fv, Fc, offset), so one least-squares
solve identifies them from one record of force and motion, open or closed loop (Gautier 1991;
Janot, Gautier and Brunot 2019, the EMPS benchmark).

How the motion is differentiated, and why it does not bias the estimate:

- The position is low-passed by a zero-phase Butterworth filter (forward and backward, so no
  lag between force and motion), then differentiated by central differences: velocity and
  acceleration with the same zero phase ("band-pass filtering").
- The regressors and the force then go through one and the same low-pass and decimation
  ("parallel filtering"). A linear filter applied to both sides of a linear-in-parameters
  equation leaves the parameters unchanged, while it removes the drive's high-frequency
  ripple and makes the remaining residuals closer to independent.
- Samples near standstill are left out: there sign(v) is not defined, the contact sticks, and
  quantisation noise decides the sign.
- The encoder quantisation is estimated from the position record, and its noise carried
  through the same filters: `velocity_noise_m_s` and `acceleration_noise_m_s2` state how
  well the derivatives are known, and `attenuation_*` how much errors-in-variables could
  shrink M and Fv (the fraction of a regressor's variance that is noise).
- Standard errors are heteroscedasticity- and autocorrelation-consistent (Newey-West, Bartlett
  kernel): the residuals of a filtered record are correlated, and the classic formula would
  state them too small. The classic ones are reported beside them.

From an acceleration record the velocity is an integral, known only up to a constant and a
ramp (an accelerometer's offset). The ramp is fitted as a nuisance regressor; the constant,
times Fv, is a force no record can tell from the offset, so the offset is reported as unknown
(NaN) and a wider standstill band keeps the drift from deciding sign(v).

Per-direction friction (Fv+, Fc+ for v > 0; Fv-, Fc- for v < 0) is fitted as a second model.
There the offset cannot be told from the difference of the two Coulomb forces, so it is left
out, as in the published asymmetric model.

No confident figures from a record this model does not describe. A mass that is not positive
beyond twice its standard error, or a relative error above `RELATIVE_ERROR_LIMIT`, means the
record is not an axis driven through its inertia: `fits_record` is False and `why` says what
is wrong. The commonest such record is an imposed-motion friction test (a reciprocating
tribometer, a friction damper on a shaker): the motion is imposed, the force is the contact's
alone, and its pre-sliding (the force turning over a small displacement after each reversal)
acts like a spring, which against a sinusoid's a = -w^2 x is fitted as a large negative mass.
Such a record is then fitted by the model it calls for (`ImposedMotionFriction`): no inertia,
Coulomb and viscous friction per direction, on the sliding part of each stroke (beyond
`PRESLIDING_STROKE_FRACTION` of the stroke after each reversal, as ASTM G133 takes friction
from the middle of the stroke), with the friction loop (force against displacement) and the
energy dissipated in each cycle (the loop's area), and what is left near the reversals.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fmm_ros._lazy import LazyModule
from fmm_ros.core.identify.spec import AxisSpec
from fmm_ros.errors import BadInputError

signal = LazyModule('scipy.signal')

DEFAULT_CUTOFF_FRACTION = 0.1
"""Position low-pass cut-off as a fraction of the sample rate (100 Hz at 1 kHz, as EMPS)."""
PARALLEL_BAND_FRACTION = 0.4
"""The parallel filter keeps this fraction of the position cut-off (40 Hz of 100 Hz)."""
STANDSTILL_NOISE_FACTOR = 5.0
"""Samples slower than this many velocity-noise levels are standstill (sign undefined)."""
MIN_STANDSTILL_SPEED_FRACTION = 0.02
"""... and never slower than this fraction of the record's RMS speed."""
DRIFT_STANDSTILL_SPEED_FRACTION = 0.25
"""The same for a velocity integrated from an acceleration, which is known only up to a drift."""
FRICTION_MAP_BINS = 24
MIN_SAMPLES_PER_BIN = 8
MOTION_KINDS = ('position', 'velocity', 'acceleration')
RELATIVE_ERROR_LIMIT = 0.10
"""Above this relative error (residual norm over force norm) a fit does not describe its record:
the axes this identifies leave a few percent (EMPS: 4 %), a missing effect tens of percent."""
MASS_SIGNIFICANCE = 2.0
"""A mass must exceed this many standard errors above zero to be reported."""
PRESLIDING_STROKE_FRACTION = 0.25
"""Imposed motion: samples within this fraction of the stroke after a reversal are pre-sliding
(the force turning from one direction's friction to the other's), not sliding."""
LOOP_POINTS = 1000
"""At most this many points of the friction loop are reported (the last whole cycle)."""


_PLAIN_AXIS = AxisSpec()
"""The default identification: a free axis, the default filters, per-direction terms."""


@dataclass(frozen=True)
class Estimate:
    """One identified parameter with its Newey-West and classic standard errors."""

    value: float
    stderr: float
    stderr_classic: float


@dataclass(frozen=True)
class FrictionMap:
    """Friction force against sliding speed: the drive force less inertia, offset and spring.

    speed_m_s: signed bin centres; friction_n: median friction force in each bin (positive
    for positive speed); count: samples in each bin.
    """

    speed_m_s: np.ndarray
    friction_n: np.ndarray
    count: np.ndarray


@dataclass(frozen=True)
class ImposedMotionFriction:
    """Friction of an imposed-motion test: no inertia, Coulomb and viscous per direction.

    F = Fc+ + Fv+ v for v > 0 and F = -Fc- + Fv- v for v < 0, fitted on the sliding samples
    (beyond PRESLIDING_STROKE_FRACTION of the stroke after each reversal). Forces in the
    force channel's unit, displacements in the motion's. loop_*: the last whole cycle's
    force against displacement; energy_per_cycle_j: the loop's area, cycle by cycle (each from
    one minimum of the displacement to the next), the energy the contact dissipated.
    residual_rms_reversals_n: the model's RMS error on the pre-sliding samples, which it does
    not describe (hysteresis or backlash near reversals).
    """

    coulomb_positive_n: Estimate
    coulomb_negative_n: Estimate
    viscous_positive_n_s_per_m: Estimate
    viscous_negative_n_s_per_m: Estimate
    relative_error_sliding: float
    residual_rms_sliding_n: float
    residual_rms_reversals_n: float
    samples_sliding: int
    samples_reversals: int
    stroke_m: float
    loop_displacement_m: np.ndarray
    loop_force_n: np.ndarray
    energy_per_cycle_j: np.ndarray

    @property
    def coulomb_asymmetry(self) -> float:
        """Fc- / Fc+ - 1: how much more friction moving negative than positive (0: none)."""
        return self.coulomb_negative_n.value / self.coulomb_positive_n.value - 1.0


@dataclass(frozen=True)
class AxisFriction:
    """The identified axis: parameters, per-direction friction, fit quality and how it was done."""

    mass_kg: Estimate
    viscous_n_s_per_m: Estimate
    coulomb_n: Estimate
    offset_n: Estimate
    directions: dict[str, Estimate] = field(default_factory=dict)
    residual_rms_n: float = math.nan
    relative_error: float = math.nan
    samples_used: int = 0
    samples_standstill: int = 0
    sample_rate_hz: float = math.nan
    cutoff_hz: float = math.nan
    decimation: int = 1
    motion: str = 'position'
    encoder_step_m: float = math.nan
    velocity_noise_m_s: float = math.nan
    acceleration_noise_m_s2: float = math.nan
    attenuation_mass: float = math.nan
    attenuation_viscous: float = math.nan
    condition_number: float = math.nan
    friction_map: FrictionMap | None = None
    fits_record: bool = True
    """False when the inertial model does not describe the record (see `why`)."""
    why: str = ''
    """What the inertial model leaves unexplained, and what was fitted instead ('' if it fits)."""
    imposed_motion: ImposedMotionFriction | None = None
    """The no-inertia fit of an imposed-motion record, when the inertial model does not fit."""


def encoder_step(position_m: np.ndarray) -> float:
    """The quantisation step of a position record [m]: its smallest common non-zero change.

    Differences below 1e-9 of the travel are treated as floating-point noise. Returns
    NaN when the record is not visibly quantised (most changes are not whole multiples of the
    smallest one), e.g. a simulated or an analogue position.
    """
    position_m = np.asarray(position_m, dtype=float)
    travel = float(np.ptp(position_m)) if position_m.size else 0.0
    steps = np.abs(np.diff(position_m))
    steps = steps[steps > 1e-9 * travel]
    if steps.size < 10:
        return math.nan
    smallest = float(steps.min())
    multiples = steps / smallest
    whole = np.abs(multiples - np.round(multiples)) < 0.05
    return smallest if whole.mean() > 0.9 else math.nan


def differentiate(
    values: np.ndarray, sample_rate_hz: float, cutoff_hz: float, times: int
) -> list[np.ndarray]:
    """`values` low-passed at cutoff_hz with zero phase, and its first `times` derivatives.

    A 4th-order Butterworth run forward and backward (no lag), then central differences
    (np.gradient, second order inside, first order at the ends).
    """
    sos = signal.butter(4, cutoff_hz, fs=sample_rate_hz, output='sos')
    smooth = signal.sosfiltfilt(sos, values)
    out = [smooth]
    for _ in range(times):
        out.append(np.gradient(out[-1], 1.0 / sample_rate_hz))
    return out


def _integrate(values: np.ndarray, sample_rate_hz: float) -> np.ndarray:
    """Trapezoidal running integral starting at zero."""
    steps = 0.5 * (values[1:] + values[:-1]) / sample_rate_hz
    return np.concatenate(([0.0], np.cumsum(steps)))


def _detrended_integral(values: np.ndarray, sample_rate_hz: float) -> np.ndarray:
    """Integral of an acceleration with its straight-line drift removed.

    A constant accelerometer offset integrates to a ramp in velocity; an axis that moves back
    and forth has no such ramp, so the best straight line through the integral is removed.
    """
    integral = _integrate(values, sample_rate_hz)
    t = np.arange(values.size) / sample_rate_hz
    return integral - np.polyval(np.polyfit(t, integral, 1), t)


def motion_states(
    motion: np.ndarray, kind: str, sample_rate_hz: float, cutoff_hz: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position [m], velocity [m/s] and acceleration [m/s^2] from one measured motion channel.

    Position is differentiated twice; velocity once (and integrated for the position, which
    only a spring needs); acceleration is integrated once with its drift removed (and twice for
    the position). Every channel passes the same zero-phase low-pass.
    """
    if kind == 'position':
        x, v, a = differentiate(motion, sample_rate_hz, cutoff_hz, 2)
    elif kind == 'velocity':
        v, a = differentiate(motion, sample_rate_hz, cutoff_hz, 1)
        x = _integrate(v, sample_rate_hz)
    elif kind == 'acceleration':
        (a,) = differentiate(motion, sample_rate_hz, cutoff_hz, 0)
        v = _detrended_integral(a, sample_rate_hz)
        x = _integrate(v, sample_rate_hz)
    else:
        raise BadInputError(f'motion kind {kind!r} is none of {", ".join(MOTION_KINDS)}')
    return x, v, a


def _derivative_gains(
    sample_rate_hz: float, cutoff_hz: float, decimation: int, band_hz: float
) -> tuple[float, float]:
    """RMS gain from white position noise to velocity and to acceleration, after all filters."""
    n = 8192
    impulse = np.zeros(n)
    impulse[n // 2] = 1.0
    _, v, a = differentiate(impulse, sample_rate_hz, cutoff_hz, 2)
    if decimation > 1:
        sos = signal.butter(8, band_hz, fs=sample_rate_hz, output='sos')
        v = signal.sosfiltfilt(sos, v)
        a = signal.sosfiltfilt(sos, a)
    return float(np.sqrt(np.sum(v**2))), float(np.sqrt(np.sum(a**2)))


def _parallel_filter(
    columns: np.ndarray, sample_rate_hz: float, band_hz: float, decimation: int
) -> np.ndarray:
    """The same zero-phase low-pass on every column, then one sample in `decimation` kept."""
    if decimation == 1:
        return columns
    sos = signal.butter(8, band_hz, fs=sample_rate_hz, output='sos')
    return signal.sosfiltfilt(sos, columns, axis=0)[::decimation]


def _least_squares(
    regressors: np.ndarray, target: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Parameters, residuals, Newey-West and classic standard errors of target ~ regressors."""
    theta, *_ = np.linalg.lstsq(regressors, target, rcond=None)
    residual = target - regressors @ theta
    n, p = regressors.shape
    bread = np.linalg.inv(regressors.T @ regressors)
    sigma2 = float(residual @ residual) / max(n - p, 1)
    classic = np.sqrt(np.diag(bread) * sigma2)
    scores = regressors * residual[:, None]
    meat = scores.T @ scores
    lags = int(math.ceil(4.0 * (n / 100.0) ** (2.0 / 9.0)))
    for lag in range(1, lags + 1):
        weight = 1.0 - lag / (lags + 1.0)
        cross = scores[lag:].T @ scores[:-lag]
        meat += weight * (cross + cross.T)
    hac = np.sqrt(np.abs(np.diag(bread @ meat @ bread)) * n / max(n - p, 1))
    return theta, residual, hac, classic


def _friction_map(speed: np.ndarray, friction: np.ndarray) -> FrictionMap:
    """Median friction in equal-count speed bins on each side of zero."""
    centres: list[float] = []
    medians: list[float] = []
    counts: list[int] = []
    for side in (-1.0, 1.0):
        mask = side * speed > 0.0
        if mask.sum() < MIN_SAMPLES_PER_BIN:
            continue
        s, f = speed[mask], friction[mask]
        bins = max(1, min(FRICTION_MAP_BINS // 2, int(mask.sum() // MIN_SAMPLES_PER_BIN)))
        edges = np.quantile(s, np.linspace(0.0, 1.0, bins + 1))
        index = np.clip(np.searchsorted(edges, s, side='right') - 1, 0, bins - 1)
        for b in range(bins):
            inside = index == b
            if inside.sum() >= MIN_SAMPLES_PER_BIN:
                centres.append(float(np.median(s[inside])))
                medians.append(float(np.median(f[inside])))
                counts.append(int(inside.sum()))
    order = np.argsort(centres)
    return FrictionMap(
        speed_m_s=np.asarray(centres)[order],
        friction_n=np.asarray(medians)[order],
        count=np.asarray(counts, dtype=int)[order],
    )


def _inertial_faults(mass: Estimate, relative_error: float) -> list[str]:
    """What keeps the inertial fit from describing its record (empty: it does)."""
    faults = []
    if not mass.value > MASS_SIGNIFICANCE * mass.stderr:
        faults.append(
            f'its mass {mass.value:.4g} ± {mass.stderr:.2g} is not positive beyond '
            f'{MASS_SIGNIFICANCE:g} standard errors'
        )
    if not relative_error <= RELATIVE_ERROR_LIMIT:
        faults.append(
            f'its relative error {100.0 * relative_error:.0f} % exceeds '
            f'{100.0 * RELATIVE_ERROR_LIMIT:.0f} %'
        )
    return faults


def _stretches(velocity: np.ndarray, moving: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First sample of each stretch of one direction among the moving samples, and its sign."""
    index = np.flatnonzero(moving)
    forward = velocity[index] > 0.0
    firsts = np.concatenate(([0], np.flatnonzero(forward[1:] != forward[:-1]) + 1))
    return index[firsts], np.where(forward[firsts], 1.0, -1.0)


def _loop_and_energy(
    position: np.ndarray, force: np.ndarray, minima: list[int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The last whole cycle's loop (at most LOOP_POINTS points) and each cycle's area ∮F dx."""
    energy = []
    for start, end in zip(minima[:-1], minima[1:], strict=False):
        x, f = position[start : end + 1], force[start : end + 1]
        energy.append(float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(x))))
    if len(minima) < 2:
        return np.empty(0), np.empty(0), np.asarray(energy)
    start, end = minima[-2], minima[-1]
    stride = max(1, math.ceil((end + 1 - start) / LOOP_POINTS))
    return position[start : end + 1 : stride], force[start : end + 1 : stride], np.asarray(energy)


def _imposed_motion(
    x_d: np.ndarray,
    v_d: np.ndarray,
    target_d: np.ndarray,
    moving: np.ndarray,
    position: np.ndarray,
    force: np.ndarray,
    decimation: int,
) -> ImposedMotionFriction | str:
    """The no-inertia, per-direction fit of an imposed-motion record, or why there is none.

    x_d, v_d, target_d, moving: the filtered, decimated record; position, force: the same at
    the full rate (decimated index j is full-rate index j * decimation).
    """
    firsts, signs = _stretches(v_d, moving)
    if firsts.size < 3:
        return 'the motion reverses fewer than two times, too few for an imposed-motion fit'
    # the turning point before each stretch: the extreme of x since the previous one began
    turns = [
        (np.argmin if sign > 0 else np.argmax)(x_d[previous : first + 1]) + previous
        for previous, first, sign in zip(firsts[:-1], firsts[1:], signs[1:], strict=True)
    ]
    turn_x = x_d[turns]
    strokes = np.abs(np.diff(turn_x))
    stroke = float(np.median(strokes)) if strokes.size else float(np.ptp(x_d))
    ends = np.concatenate((firsts[2:], [x_d.size]))
    sliding = np.zeros(x_d.size, dtype=bool)
    reversing = np.zeros(x_d.size, dtype=bool)
    for k, (first, end) in enumerate(zip(firsts[1:], ends, strict=True)):
        length = strokes[k] if k < strokes.size else stroke
        inside = np.zeros(x_d.size, dtype=bool)
        inside[first:end] = True
        inside &= moving
        near = np.abs(x_d - turn_x[k]) < PRESLIDING_STROKE_FRACTION * length
        sliding |= inside & ~near
        reversing |= inside & near
    forward = (v_d > 0.0).astype(float)
    backward = 1.0 - forward
    columns = np.column_stack((forward, v_d * forward, -backward, v_d * backward))
    if min(int((sliding & (forward > 0)).sum()), int((sliding & (backward > 0)).sum())) < 10:
        return 'too few sliding samples in one direction for an imposed-motion fit'
    theta, residual, hac, classic = _least_squares(columns[sliding], target_d[sliding])
    relative = float(np.linalg.norm(residual) / np.linalg.norm(target_d[sliding]))
    if not relative <= RELATIVE_ERROR_LIMIT:
        return (
            'the imposed-motion model (no inertia, Coulomb and viscous per direction) does not '
            f'describe it either: relative error {100.0 * relative:.0f} % on the sliding part'
        )
    left = target_d[reversing] - columns[reversing] @ theta
    minima = []
    for turn, sign in zip(turns, signs[1:], strict=True):
        if sign > 0:  # a minimum of x: the full-rate one within a decimation step of it
            low = max(0, (turn - 1) * decimation)
            minima.append(int(np.argmin(position[low : (turn + 1) * decimation + 1]) + low))
    loop_x, loop_f, energy = _loop_and_energy(position, force, minima)
    estimates = [
        Estimate(float(t), float(h), float(c)) for t, h, c in zip(theta, hac, classic, strict=True)
    ]
    return ImposedMotionFriction(
        coulomb_positive_n=estimates[0],
        viscous_positive_n_s_per_m=estimates[1],
        coulomb_negative_n=estimates[2],
        viscous_negative_n_s_per_m=estimates[3],
        relative_error_sliding=relative,
        residual_rms_sliding_n=float(np.sqrt(np.mean(residual**2))),
        residual_rms_reversals_n=float(np.sqrt(np.mean(left**2))) if left.size else math.nan,
        samples_sliding=int(sliding.sum()),
        samples_reversals=int(reversing.sum()),
        stroke_m=stroke,
        loop_displacement_m=loop_x,
        loop_force_n=loop_f,
        energy_per_cycle_j=energy,
    )


def _check_record(force_n: np.ndarray, motion: np.ndarray, sample_rate_hz: float) -> None:
    if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0.0):
        raise BadInputError(f'sample rate must be positive and finite, got {sample_rate_hz}')
    if force_n.ndim != 1 or motion.ndim != 1 or force_n.size != motion.size:
        raise BadInputError(
            f'force and motion must be vectors of one length, got {force_n.shape} and '
            f'{motion.shape}'
        )
    for name, values in (('force', force_n), ('motion', motion)):
        bad = ~np.isfinite(values)
        if bad.any():
            raise BadInputError(f'{name} is not finite at sample {int(np.argmax(bad))}')


def identify_axis_friction(
    force_n: np.ndarray,
    motion: np.ndarray,
    sample_rate_hz: float,
    *,
    motion_kind: str = 'position',
    spec: AxisSpec = _PLAIN_AXIS,
) -> AxisFriction:
    """Identify M, Fv, Fc and offset of a drive from its force [N] and motion (SI units).

    motion is a position [m], velocity [m/s] or acceleration [m/s^2] record, as motion_kind
    says, sampled with the force at sample_rate_hz. BadInputError when the record cannot
    identify the axis (too short, never moving, or moving one way only).
    """
    force_n = np.asarray(force_n, dtype=float)
    motion = np.asarray(motion, dtype=float)
    _check_record(force_n, motion, sample_rate_hz)
    cutoff, band, decimation, border = _filter_plan(force_n.size, sample_rate_hz, spec)
    x, v, a = motion_states(motion, motion_kind, sample_rate_hz, cutoff)
    target = force_n - spec.stiffness_n_per_m * x
    sign = np.sign(v)
    core = slice(border, force_n.size - border)
    columns = np.column_stack((a, v, sign, np.ones_like(v), target))[core]
    filtered = _parallel_filter(columns, sample_rate_hz, band, decimation)
    a_d, v_d, sign_d, ones_d, target_d = filtered.T

    step = encoder_step(motion) if motion_kind == 'position' else math.nan
    noise_v, noise_a = _quantisation_noise(step, sample_rate_hz, cutoff, decimation, band)
    drifting = motion_kind == 'acceleration'
    moving = _moving_both_ways(v_d, _standstill_speed(v_d, noise_v, drifting))

    # From an acceleration, the velocity is known up to a constant, which Fv turns into a
    # force indistinguishable from the offset, and up to a ramp (an accelerometer offset),
    # fitted as a nuisance column: the offset is then reported as not identifiable.
    time_d = np.linspace(-1.0, 1.0, v_d.size)
    nuisance = (time_d,) if drifting else ()
    regressors = np.column_stack((a_d, v_d, sign_d, ones_d, *nuisance))[moving]
    estimates, residual = _inertial_estimates(regressors, target_d[moving], drifting)
    directions = _per_direction(a_d, v_d, nuisance, target_d, moving) if spec.per_direction else {}
    mass, viscous, coulomb, offset = estimates
    relative_error = float(np.linalg.norm(residual) / np.linalg.norm(target_d[moving]))
    faults = _inertial_faults(mass, relative_error)
    imposed: ImposedMotionFriction | None = None
    why = ''
    if faults:
        (x_d,) = _parallel_filter(x[core][:, None], sample_rate_hz, band, decimation).T
        fitted = _imposed_motion(x_d, v_d, target_d, moving, x[core], target[core], decimation)
        imposed = None if isinstance(fitted, str) else fitted
        why = _why_not_inertial(faults, fitted)
    friction = (
        target_d - mass.value * a_d - (0.0 if drifting else offset.value)
        if not faults
        else target_d
    )
    return AxisFriction(
        mass_kg=mass,
        viscous_n_s_per_m=viscous,
        coulomb_n=coulomb,
        offset_n=offset,
        directions=directions,
        residual_rms_n=float(np.sqrt(np.mean(residual**2))),
        relative_error=relative_error,
        samples_used=int(moving.sum()),
        samples_standstill=int((~moving).sum()),
        sample_rate_hz=float(sample_rate_hz),
        cutoff_hz=float(cutoff),
        decimation=int(decimation),
        motion=motion_kind,
        encoder_step_m=step,
        velocity_noise_m_s=noise_v,
        acceleration_noise_m_s2=noise_a,
        attenuation_mass=_attenuation(noise_a, a_d[moving]),
        attenuation_viscous=_attenuation(noise_v, v_d[moving]),
        condition_number=float(np.linalg.cond(regressors)),
        friction_map=_friction_map(v_d[moving], friction[moving]),
        fits_record=not faults,
        why=why,
        imposed_motion=imposed,
    )


def _inertial_estimates(
    regressors: np.ndarray, target: np.ndarray, drifting: bool
) -> tuple[list[Estimate], np.ndarray]:
    """M, Fv, Fc and offset with their errors from the moving samples, and the fit's residual.

    regressors: a, v, sign(v), 1 and any nuisance columns, whose values are not reported.
    drifting (motion from an acceleration): the offset is not identifiable, so it is NaN.
    """
    theta, residual, hac, classic = _least_squares(regressors, target)
    estimates = [
        Estimate(float(t), float(h), float(c))
        for t, h, c in zip(theta[:4], hac[:4], classic[:4], strict=True)
    ]
    if drifting:
        estimates[3] = Estimate(math.nan, math.nan, math.nan)
    return estimates, residual


def _attenuation(noise: float, state: np.ndarray) -> float:
    """The fraction of a regressor's variance that is its noise (NaN if it does not vary).

    It says how much errors-in-variables could shrink the state's coefficient (M or Fv).
    """
    variance = float(np.var(state))
    return noise**2 / variance if variance > 0 else math.nan


def _standstill_speed(v_d: np.ndarray, noise_v: float, drifting: bool) -> float:
    """The speed [m/s] below which a sample counts as standing still, left out of the fit.

    Above the velocity noise and a fraction of the record's RMS speed (a larger fraction for
    a velocity integrated from an acceleration, which is known only up to a drift).
    """
    fraction = DRIFT_STANDSTILL_SPEED_FRACTION if drifting else MIN_STANDSTILL_SPEED_FRACTION
    rms_speed = float(np.sqrt(np.mean(v_d**2)))
    return max(STANDSTILL_NOISE_FACTOR * noise_v, fraction * rms_speed)


def _quantisation_noise(
    step: float, sample_rate_hz: float, cutoff: float, decimation: int, band: float
) -> tuple[float, float]:
    """The velocity [m/s] and acceleration [m/s^2] noise an encoder's step puts in the states.

    A step's quantisation (step / sqrt(12) RMS, none without a step) through the filters'
    derivative gains: the standstill threshold and the attenuation of M and Fv rest on it.
    """
    gain_v, gain_a = _derivative_gains(sample_rate_hz, cutoff, decimation, band)
    quantisation = step / math.sqrt(12.0) if math.isfinite(step) else 0.0
    return quantisation * gain_v, quantisation * gain_a


def _why_not_inertial(faults: list[str], fitted: ImposedMotionFriction | str) -> str:
    """Why the inertial model was refused, and what the imposed-motion fit made of the record.

    fitted: the imposed-motion fit, or why it could not be made. The text goes in
    `AxisFriction.why`, so a reader sees what is left unexplained (reversal hysteresis).
    """
    why = 'the inertial model does not describe this record: ' + '; '.join(faults) + '. '
    if isinstance(fitted, str):
        return why + f'No other model was fitted: {fitted}.'
    return why + (
        'Fitted as an imposed-motion friction test instead (no inertia, Coulomb and '
        'viscous friction per direction) on the sliding part of each stroke, relative '
        f'error {100.0 * fitted.relative_error_sliding:.1f} % there. Left unexplained: '
        'hysteresis near reversals (pre-sliding or backlash), residual '
        f'{fitted.residual_rms_reversals_n:.3g} RMS within the first '
        f'{100.0 * PRESLIDING_STROKE_FRACTION:.0f} % of each stroke against '
        f'{fitted.residual_rms_sliding_n:.3g} when sliding.'
    )


def _filter_plan(size: int, sample_rate_hz: float, spec: AxisSpec) -> tuple[float, float, int, int]:
    """The filters' cutoff [Hz], parallel band [Hz], decimation and border [samples].

    BadInputError when the cutoff is not below the Nyquist frequency, or the record is too
    short for the filters.
    """
    nyquist = 0.5 * sample_rate_hz
    cutoff = spec.cutoff_hz or DEFAULT_CUTOFF_FRACTION * sample_rate_hz
    if cutoff >= nyquist:
        raise BadInputError(
            f'cutoff {cutoff:g} Hz must lie below the Nyquist frequency {nyquist:g} Hz'
        )
    band = PARALLEL_BAND_FRACTION * cutoff
    decimation = spec.decimation or max(1, round(0.8 * nyquist / band))
    border = int(math.ceil(5.0 * sample_rate_hz / cutoff))
    if size < 2 * border + 20 * decimation:
        raise BadInputError(
            f'{size} samples are too few to identify an axis at {sample_rate_hz:g} Hz '
            f'(filters need {2 * border + 20 * decimation})'
        )
    return cutoff, band, decimation, border


def _moving_both_ways(v_d: np.ndarray, standstill_speed: float) -> np.ndarray:
    """The samples faster than standstill; BadInputError unless they go both ways."""
    moving = np.abs(v_d) > standstill_speed
    if moving.sum() < 10 or not ((v_d[moving] > 0).any() and (v_d[moving] < 0).any()):
        raise BadInputError(
            'the axis must move both ways for friction to be told from the offset: '
            f'{int((v_d > standstill_speed).sum())} samples move forward and '
            f'{int((v_d < -standstill_speed).sum())} backward above {standstill_speed:.3g} m/s'
        )
    return moving


def _per_direction(
    a_d: np.ndarray,
    v_d: np.ndarray,
    nuisance: tuple[np.ndarray, ...],
    target_d: np.ndarray,
    moving: np.ndarray,
) -> dict[str, Estimate]:
    """M and each direction's own Fv and Fc, fitted over the moving samples."""
    forward = (v_d > 0.0).astype(float)
    backward = 1.0 - forward
    columns = (a_d, v_d * forward, forward, v_d * backward, -backward, *nuisance)
    theta2, _, hac2, classic2 = _least_squares(np.column_stack(columns)[moving], target_d[moving])
    names = ('mass_kg', 'viscous_positive', 'coulomb_positive', 'viscous_negative')
    names += ('coulomb_negative',)
    return {
        name: Estimate(float(t), float(h), float(c))
        for name, t, h, c in zip(names, theta2, hac2, classic2, strict=False)
    }
