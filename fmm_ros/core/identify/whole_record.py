"""A whole record driven by its measured force: the rig and the missing terms, by output error.

Not every record is a set of hits. A shaker's random noise, a multisine, a sine sweep or a
closed-loop move drives the structure throughout, and the whole record is one excitation:

    m x'' + c x' + k x + k3 x^3 + Fc sign(x') = f(t) + f0,

with m, c, k the rig (fitted when unknown, `fit_rig`), f0 a constant force (a sensor's zero),
and k3 (`cubic_stiffness`) and Fc (`coulomb_friction`) the candidate terms. The measured
force drives the model; the simulated displacement is compared with the measured one (output
error), so the noise on the displacement does not bias the estimate as it biases a fit of
the equation itself to differentiated data (equation error).

How the force is treated between samples. At low rates a resonance has few samples a period
(Silverbox: 62 Hz at 610 Hz, ten), and a force held constant between samples (zero-order
hold) would shift the model's phase by half a sample. The force is taken as continuous, a
straight line between samples (first-order hold), and the linear part is discretised exactly
for that input (the matrix exponential of the augmented system, Franklin, Powell and Workman,
"Digital Control of Dynamic Systems", Sec. 6.3). The cubic spring's force at the end of a step
depends on the position there: it is solved for by Newton's method within the step, so the
nonlinear term enters with the same first-order hold. The friction force takes the sign of the
velocity at the start of each step.

A term is named when it halves the gap (the residual's RMS over the displacement's, the
normalised output error) beyond the model without it, and its coefficient exceeds three of
its standard errors; terms are added greedily, the best first, as the impact diagnosis does.
Standard errors are Newey-West (Bartlett kernel) on the output-error Jacobian: the residuals
of a record are correlated in time, and the classic formula would state them too small.

The numbers are in the channels' own units: N and m, or V for an uncalibrated channel (then m
is in V s^2/V and so on); the names stay SI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np
from scipy import linalg, optimize, signal

from fmm_ros.errors import BadInputError

CANDIDATE_TERMS = ('cubic_stiffness', 'coulomb_friction')
"""The terms a whole record is screened for, beyond the linear rig."""
GAP_RATIO_TO_NAME = 0.5
"""A term is named when the gap with it is at most this fraction of the gap without it."""
SIGNIFICANCE = 3.0
"""... and its coefficient exceeds this many of its standard errors."""
MIN_SAMPLES_PER_PERIOD = 4.0
"""Below this many samples a period of the fitted resonance the record cannot identify it."""
NEWTON_STEPS = 4
"""Newton steps for the cubic spring's position at the end of a step, from the linear
prediction: the correction is gamma1 k3 x^2 of it (1e-3 on Silverbox), so each step squares
a relative error already below 1e-3, and four reach rounding."""
PARAMETERS = ('mass', 'damping', 'stiffness', 'offset')
"""The linear rig's parameters, then the offset force; the terms' coefficients follow."""


@dataclass(frozen=True)
class WholeRecordFit:
    """One output-error fit of a whole record: parameters, standard errors, gap.

    values and stderr by name: mass, damping, stiffness (the rig, in force / displacement
    units times s^2, s, 1), offset (force), and each term's coefficient (cubic_stiffness:
    force per displacement^3; coulomb_friction: force). gap: RMS residual over RMS displacement.
    """

    terms: tuple[str, ...]
    values: dict[str, float]
    stderr: dict[str, float]
    gap: float
    residual_rms: float
    iterations: int

    @property
    def natural_frequency_hz(self) -> float:
        """sqrt(k/m)/2 pi of the linear part (the small-amplitude resonance) [Hz]."""
        k, m = self.values['stiffness'], self.values['mass']
        return math.sqrt(k / m) / (2.0 * math.pi) if k > 0.0 and m > 0.0 else math.nan


@dataclass(frozen=True)
class WholeRecordDiagnosis:
    """The base (linear) fit, each candidate's, the named terms and the final fit."""

    base: WholeRecordFit
    candidates: dict[str, WholeRecordFit]
    named: tuple[str, ...]
    final: WholeRecordFit
    sample_rate_hz: float
    samples: int
    why: dict[str, str] = field(default_factory=dict)
    """For each candidate not named: why (the gap it leaves, its significance)."""


def foh_matrices(
    mass: float, damping: float, stiffness: float, step_s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact first-order-hold discretisation of m x'' + c x' + k x = g.

    Returns (phi, gamma0, gamma1): state (x, v) at the next sample is
    phi @ state + gamma0 * g_now + gamma1 * g_next, exact for g linear between samples.
    """
    a = np.array([[0.0, 1.0], [-stiffness / mass, -damping / mass]])
    b = np.array([0.0, 1.0 / mass])
    augmented = np.zeros((4, 4))
    augmented[:2, :2] = a * step_s
    augmented[:2, 2] = b * step_s
    augmented[2, 3] = 1.0
    exponential = linalg.expm(augmented)
    phi = exponential[:2, :2]
    hold, ramp = exponential[:2, 2], exponential[:2, 3]
    return phi, hold - ramp, ramp


@numba.njit(cache=True, nogil=True)
def _simulate(force, phi, gamma0, gamma1, cubic, coulomb, offset, out):  # pragma: no cover
    """Displacement driven by force (+ offset) with the cubic spring and Coulomb friction."""
    x = 0.0
    v = 0.0
    g_now = force[0] + offset
    for n in range(force.size - 1):
        out[n] = x
        friction = coulomb * (1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0))
        base = force[n + 1] + offset - friction
        px = phi[0, 0] * x + phi[0, 1] * v + gamma0[0] * g_now + gamma1[0] * base
        pv = phi[1, 0] * x + phi[1, 1] * v + gamma0[1] * g_now + gamma1[1] * base
        # x_next = px - gamma1[0] k3 x_next^3: Newton from the linear prediction
        x_next = px
        if cubic != 0.0:
            stiff = gamma1[0] * cubic
            for _ in range(NEWTON_STEPS):
                square = x_next * x_next
                x_next -= (x_next + stiff * square * x_next - px) / (1.0 + 3.0 * stiff * square)
        spring = cubic * x_next * x_next * x_next
        v = pv - gamma1[1] * spring
        x = x_next
        g_now = base - spring
    out[force.size - 1] = x


def simulate_whole_record(
    force: np.ndarray, sample_rate_hz: float, values: dict[str, float]
) -> np.ndarray:
    """The model's displacement for a force record, from rest at the first sample."""
    phi, gamma0, gamma1 = foh_matrices(
        values['mass'], values['damping'], values['stiffness'], 1.0 / sample_rate_hz
    )
    out = np.empty(force.size)
    _simulate(
        np.ascontiguousarray(force, dtype=float),
        phi,
        gamma0,
        gamma1,
        float(values.get('cubic_stiffness', 0.0)),
        float(values.get('coulomb_friction', 0.0)),
        float(values.get('offset', 0.0)),
        out,
    )
    return out


def equation_error_start(
    force: np.ndarray, displacement: np.ndarray, sample_rate_hz: float
) -> dict[str, float]:
    """A start for the output-error fit: m, c, k, f0 by least squares on the equation.

    The displacement is low-passed (zero phase, at 0.4 of the rate) and differentiated by
    central differences; the force passes the same filter. Biased by the noise (equation
    error), which the output-error fit then removes.
    """
    sos = signal.butter(4, 0.4 * sample_rate_hz, fs=sample_rate_hz, output='sos')
    x = signal.sosfiltfilt(sos, displacement)
    f = signal.sosfiltfilt(sos, force)
    step = 1.0 / sample_rate_hz
    v = np.gradient(x, step)
    a = np.gradient(v, step)
    columns = np.column_stack((a, v, x, -np.ones_like(x)))
    theta, *_ = np.linalg.lstsq(columns[2:-2], f[2:-2], rcond=None)
    return dict(zip(PARAMETERS, (float(t) for t in theta), strict=True))


def _newey_west(jacobian: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """Heteroscedasticity- and autocorrelation-consistent standard errors of an OLS-like fit."""
    n, p = jacobian.shape
    bread = np.linalg.pinv(jacobian.T @ jacobian)
    scores = jacobian * residual[:, None]
    meat = scores.T @ scores
    lags = int(math.ceil(4.0 * (n / 100.0) ** (2.0 / 9.0)))
    for lag in range(1, lags + 1):
        cross = scores[lag:].T @ scores[:-lag]
        meat += (1.0 - lag / (lags + 1.0)) * (cross + cross.T)
    return np.sqrt(np.abs(np.diag(bread @ meat @ bread)) * n / max(n - p, 1))


def fit_whole_record(
    force: np.ndarray,
    displacement: np.ndarray,
    sample_rate_hz: float,
    *,
    terms: tuple[str, ...] = (),
    start: dict[str, float] | None = None,
    rig: dict[str, float] | None = None,
) -> WholeRecordFit:
    """Output-error fit of the rig (unless `rig` fixes mass, damping, stiffness) and `terms`.

    start: initial values (default: the equation-error estimate, terms at zero).
    """
    force, displacement = _check(force, displacement, sample_rate_hz)
    for term in terms:
        if term not in CANDIDATE_TERMS:
            raise BadInputError(f'term {term!r} is none of {", ".join(CANDIDATE_TERMS)}')
    initial = dict(start or equation_error_start(force, displacement, sample_rate_hz))
    if rig is not None:
        initial.update(rig)
    free = [name for name in PARAMETERS if rig is None or name not in rig] + list(terms)
    for name in terms:
        initial.setdefault(name, 0.0)
    # scales: the rig's own size, and for the terms the size that makes them matter
    rms_x = float(np.sqrt(np.mean(displacement**2)))
    stiffness = abs(initial['stiffness']) or 1.0
    scale = {
        'mass': abs(initial['mass']) or 1.0,
        'damping': abs(initial['damping']) or 1.0,
        'stiffness': stiffness,
        'offset': stiffness * rms_x,
        'cubic_stiffness': stiffness / rms_x**2,
        'coulomb_friction': stiffness * rms_x,
    }
    scales = np.array([scale[name] for name in free])

    def values_of(theta: np.ndarray) -> dict[str, float]:
        out = dict(initial)
        out.update(zip(free, (float(t) for t in theta * scales), strict=True))
        return out

    def residual(theta: np.ndarray) -> np.ndarray:
        values = values_of(theta)
        if values['mass'] <= 0.0:
            return np.full(displacement.size, 1e3 * rms_x)
        model = simulate_whole_record(force, sample_rate_hz, values)
        out = model - displacement
        return np.where(np.isfinite(out), out, 1e3 * rms_x)

    theta0 = np.array([initial[name] for name in free]) / scales
    solution = optimize.least_squares(residual, theta0, method='lm', x_scale=1.0)
    values = values_of(solution.x)
    errors = _newey_west(solution.jac, solution.fun) * scales
    rms = float(np.sqrt(np.mean(solution.fun**2)))
    return WholeRecordFit(
        terms=tuple(terms),
        values=values,
        stderr={name: float(e) for name, e in zip(free, errors, strict=True)},
        gap=rms / rms_x,
        residual_rms=rms,
        iterations=int(solution.nfev),
    )


def diagnose_whole_record(
    force: np.ndarray,
    displacement: np.ndarray,
    sample_rate_hz: float,
    *,
    rig: dict[str, float] | None = None,
    candidates: tuple[str, ...] = CANDIDATE_TERMS,
) -> WholeRecordDiagnosis:
    """Fit the linear base, screen each candidate term, name those that halve the gap.

    rig: known mass, damping, stiffness (None: fitted from the record, `--fit-rig`).
    BadInputError when the fitted resonance has too few samples a period to be identified.
    """
    force, displacement = _check(force, displacement, sample_rate_hz)
    start = equation_error_start(force, displacement, sample_rate_hz)
    base = fit_whole_record(force, displacement, sample_rate_hz, start=start, rig=rig)
    resonance = base.natural_frequency_hz
    if not resonance > 0.0 or sample_rate_hz / resonance < MIN_SAMPLES_PER_PERIOD:
        raise BadInputError(
            f'the fitted resonance {resonance:.4g} Hz has fewer than '
            f'{MIN_SAMPLES_PER_PERIOD:g} samples a period at {sample_rate_hz:g} Hz (or none: '
            f'mass {base.values["mass"]:.4g}, stiffness {base.values["stiffness"]:.4g}); '
            'the record cannot identify the rig'
        )
    named: list[str] = []
    current = base
    screened: dict[str, WholeRecordFit] = {}
    why: dict[str, str] = {}
    remaining = list(candidates)
    while remaining:
        tried = {
            term: fit_whole_record(
                force,
                displacement,
                sample_rate_hz,
                terms=(*named, term),
                start=current.values,
                rig=rig,
            )
            for term in remaining
        }
        if not screened:
            screened = dict(tried)
        best = min(tried, key=lambda term: tried[term].gap)
        fit = tried[best]
        ratio = fit.gap / current.gap
        z = abs(fit.values[best]) / fit.stderr[best] if fit.stderr[best] > 0 else math.inf
        if ratio <= GAP_RATIO_TO_NAME and z > SIGNIFICANCE:
            named.append(best)
            current = fit
            remaining.remove(best)
            continue
        for term in remaining:
            other = tried[term]
            z = abs(other.values[term]) / other.stderr[term] if other.stderr[term] else math.inf
            why[term] = (
                f'gap {other.gap:.4g} against {current.gap:.4g} without it '
                f'(ratio {other.gap / current.gap:.2f}, {GAP_RATIO_TO_NAME:g} needed), '
                f'coefficient {z:.1f} standard errors'
            )
        break
    return WholeRecordDiagnosis(
        base=base,
        candidates=screened,
        named=tuple(named),
        final=current,
        sample_rate_hz=float(sample_rate_hz),
        samples=int(force.size),
        why=why,
    )


def _check(
    force: np.ndarray, displacement: np.ndarray, sample_rate_hz: float
) -> tuple[np.ndarray, np.ndarray]:
    """Finite vectors of one length and a positive rate, or BadInputError naming which."""
    force = np.asarray(force, dtype=float)
    displacement = np.asarray(displacement, dtype=float)
    if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0.0):
        raise BadInputError(f'sample rate must be positive and finite, got {sample_rate_hz}')
    if force.ndim != 1 or force.shape != displacement.shape:
        raise BadInputError(
            f'force and displacement must be vectors of one length, got {force.shape} and '
            f'{displacement.shape}'
        )
    if force.size < 100:
        raise BadInputError(f'{force.size} samples are too few for a whole-record fit (100)')
    for name, values in (('force', force), ('displacement', displacement)):
        bad = ~np.isfinite(values)
        if bad.any():
            raise BadInputError(f'{name} is not finite at sample {int(np.argmax(bad))}')
    if not np.ptp(displacement) > 0.0:
        raise BadInputError('displacement does not move: nothing to fit')
    return force, displacement
