"""The yardstick of 'unexplained': the noise the records really carry, and the model's own error.

'unexplained' says the best model leaves a misfit beyond the noise. Two things made that
judgement uncalibrated on data from outside our own simulator:

- The noise level came from second differences (`velocity_noise_std`), which see white noise
  only. Coloured noise (a vibrometer's demodulator, a filter's correlated output), mains hum
  and a wandering zero add variance the second differences barely see, and all of it was
  counted as misfit. `rest_noise_std` measures the noise where the rig is at rest: the
  samples of each record before its hit and after its measured motion (`measured_motion_stop`),
  each stretch about its own mean (an offset is a model term the diagnosis must still see;
  its spread is noise). The total variance of stationary noise is the same whatever its
  colour, so the misfit's mean square over the motion less this variance is the model's
  error, on average, for white and coloured noise alike.
- The model drives Eq. 3 with the sampled force, whose impulse a sampled, filtered, gated
  pulse misstates by 1e-4 to 1e-3 (the force between samples, a sub-sample onset, the feet
  of a pulse below the gate's threshold, a baseline that wanders under the gate). A relative
  impulse error e moves the whole decay by e times its speed: 1e-3 of a 0.3 m/s hit is three
  noise deviations at the start of the decay. `fmm fit` fits each hit's impulse scale for
  this reason. The diagnosis's models do not (a candidate would buy its fit with a hit's
  impulse), so the verdict takes it up here, as a nuisance: `without_impulse_error` removes
  from each hit's residual its least-squares multiple of the response to a relative impulse
  change, bounded by `IMPULSE_SCALE_TOLERANCE`, so the rest is what no plausible impulse
  explains.
"""

import math
from collections.abc import Sequence

import numpy as np

from fmm_ros.core._threads import thread_map
from fmm_ros.core.diagnose.session_model import SessionModel
from fmm_ros.core.identify.conditioning import ConditionedImpact
from fmm_ros.core.identify.lsq import inner

IMPULSE_SCALE_TOLERANCE = 0.01
"""Largest relative impulse error the verdict attributes to the force's sampling [-]: the
bound `fmm fit`'s impulse scale is documented to need (sampling, filtering and noise misstate
an impulse by 1e-4 to 1e-2); anything beyond it is the model's to explain."""


MIN_REST_SAMPLES = 2000
"""Samples at rest needed to measure the noise there (0.2 s at 10 kHz: its variance to 3 %);
with fewer, the white-noise level from second differences stands in."""


IMPULSE_STEP = 1e-3
"""Relative impulse change of the finite difference that gives the response's sensitivity."""


MU_STEP = 1e-3
"""Relative change of mu of the finite difference that gives the response's sensitivity."""


def rest_noise_std(
    impacts: Sequence[ConditionedImpact], stop_index: int, white_noise_std_m_s: float
) -> float:
    """Velocity noise where the rig rests: before each hit and after its motion [m/s].

    impacts: the whole conditioned records; stop_index: the sample where the measured motion
    of every record has ended (`measured_motion_stop`, the diagnosis's crop). Each stretch
    at rest contributes its squares about its own mean; pooled over every record. Fewer than
    MIN_REST_SAMPLES at rest: white_noise_std_m_s is returned.
    """
    squares, count = 0.0, 0
    for impact in impacts:
        velocity = impact.velocity_m_s
        for stretch in (velocity[: impact.gate[0][0]], velocity[stop_index:]):
            if stretch.size >= 2:
                centred = stretch - float(np.mean(stretch))
                squares += inner(centred, centred)
                count += stretch.size - 1
    if count < MIN_REST_SAMPLES:
        return white_noise_std_m_s
    return math.sqrt(squares / count)


def _solve_with_impulse_bounds(normal: np.ndarray, projected: np.ndarray, count: int) -> np.ndarray:
    """The least-squares step of the normal equations, each impulse error held to the tolerance.

    The first `count` columns are the hits' relative impulse errors, the rest mu shifts. An
    impulse error past +-IMPULSE_SCALE_TOLERANCE is clipped to the bound and fixed there, and
    the other columns solved again given it, until none is past (at most one pass per hit and
    one more): a calibration cannot be off by more than the tolerance, so a larger error must
    not be used to explain a residual away.
    """
    columns = len(projected)
    values = np.zeros(columns)
    free = np.ones(columns, dtype=bool)
    for _ in range(count + 1):
        rest = projected[free] - normal[np.ix_(free, ~free)] @ values[~free]
        values[free] = np.linalg.lstsq(normal[np.ix_(free, free)], rest, rcond=None)[0]
        beyond = free.copy()
        beyond[count:] = False
        beyond &= np.abs(values) > IMPULSE_SCALE_TOLERANCE
        if not beyond.any():
            break
        values[beyond] = np.clip(values[beyond], -IMPULSE_SCALE_TOLERANCE, IMPULSE_SCALE_TOLERANCE)
        free &= ~beyond
    return values


def without_impulse_error(
    impacts: Sequence[ConditionedImpact],
    model: SessionModel,
    residuals: Sequence[np.ndarray],
    windows: Sequence[slice],
) -> tuple[np.ndarray, ...]:
    """The residuals less what each hit's impulse error, and mu moving with it, explain.

    impacts: the cropped impacts the model was fitted to; residuals their measured minus model
    velocity; windows the motion windows that are judged. One linearised least-squares step
    over the windows in a relative impulse error per hit and a shift of mu (one for the
    session, or each hit's own once mu_drift is named), as `fmm fit`'s impulse scales would
    move the fit; an impulse error beyond +-IMPULSE_SCALE_TOLERANCE is held at the bound and
    the rest solved again. In a chained session (`ConditionedImpact.follows_previous`) a hit's
    impulse and mu also move where it leaves the rig, so the later hits' starts: their
    responses count too (`SessionModel.moved_along_chain`).
    """
    count = len(impacts)
    own_mu = bool(model.per_hit)
    columns = 2 * count if own_mu else count + 1
    # Sensitivities of each hit's velocity over its window, by column; the normal equations
    # are summed hit by hit, never the (samples x columns) design.
    rows: list[dict[int, np.ndarray]] = [{} for _ in impacts]
    nominal = [
        impact.velocity_m_s - residual for impact, residual in zip(impacts, residuals, strict=True)
    ]
    rests = model.rests_m(impacts)
    mus = [float(mu) for mu in model.mus]
    hits = [[index] for index in range(count)]

    def sensitivities(column: int, changed: list[int]) -> dict[int, np.ndarray]:
        """Each moved hit's velocity per unit of a column, in its window.

        Columns below `count` are a hit's relative impulse error, the others a mu.
        """
        impulse = column < count
        step = IMPULSE_STEP if impulse else MU_STEP * mus[changed[0]]
        change = {
            index: {'force_n': impacts[index].force_n * (1.0 + step)}
            if impulse
            else {'mu': mus[index] + step}
            for index in changed
        }
        return {
            index: ((velocity - nominal[index]) / step)[windows[index]]
            for index, velocity in model.moved_along_chain(impacts, rests, change).items()
        }

    changes = list(enumerate(hits + (hits if own_mu else [list(range(count))])))
    for (column, _), moved in zip(
        changes, thread_map(lambda item: sensitivities(*item), changes), strict=True
    ):
        for index, row in moved.items():
            rows[index][column] = row
    normal = np.zeros((columns, columns))
    projected = np.zeros(columns)
    blocks = []
    for own, residual, window in zip(rows, residuals, windows, strict=True):
        where = list(own)
        pair = np.stack([own[column] for column in where])
        normal[np.ix_(where, where)] += inner(pair, pair)
        projected[where] += inner(pair, residual[window])
        blocks.append((where, pair))
    values = _solve_with_impulse_bounds(normal, projected, count)
    out = []
    for residual, window, (where, pair) in zip(residuals, windows, blocks, strict=True):
        corrected = residual.copy()
        corrected[window] -= values[where] @ pair
        out.append(corrected)
    return tuple(out)
