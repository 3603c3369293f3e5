"""Screening: how far each candidate could lower chi^2, from one linearised step, before a refit.

A refit costs tens of model runs per hit (hundreds on the RK4 path of a Stribeck or cubic
term); most candidates have nothing to find. Each is first screened at the current model:

- the candidate's response shape, d_i = v_i(model + term at a probe size) - v_i(model), one
  model run per hit per probe (the Stribeck term at three speeds v_s, the second mode at the
  strongest residual peak with three damping ratios);
- the nuisance directions the refit would also move: d v_i / d mu (one mu for all hits, or
  each hit's own once mu drifts) and d v_i / d x0_i (each hit's start, when fitted), by
  forward differences, one run per hit each;
- least squares of the residual on them, the starts eliminated hit by hit (Schur complement):
  the fall of chi^2 that adding the candidate's direction buys beyond the nuisance ones is
  the score statistic of the candidate (the Gauss-Newton step's predicted gain), and its
  coefficient scales the probe into the refit's start.

`mu_drift` is screened the same way with no extra model run: the gain of one mu per hit over
one mu for all, and the linearised per-hit mu it gives; its detection limit is that of a
steady change of mu from hit to hit.

With more than SCREEN_HITS hits the terms are screened on SCREEN_HITS of them spread over the
session, and the gain scaled by the hits' count over theirs (a term acts on every hit): the
screen only ranks and gates refits, and each probe of a nonlinear term costs a run on the RK4
path per hit. mu_drift, which is about every hit, is screened on all.
"""

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from fmm_ros.constants import MU_DRIFT
from fmm_ros.core._threads import thread_map
from fmm_ros.core.diagnose.session_model import SessionModel
from fmm_ros.core.identify.conditioning import ConditionedImpact
from fmm_ros.core.identify.lsq import inner
from fmm_ros.core.physics.model import mode_velocity
from fmm_ros.core.physics.terms import EFFECT_SIZE, MODEL_TERMS, ModelTerm, model_spec
from fmm_ros.errors import BadInputError

RELATIVE_STEP = 1e-4
"""Forward-difference step of mu and of a start position, relative to their scale."""


SCREEN_HITS = 8
"""Terms are screened on at most this many hits, spread over the session."""


def screened_hits(count: int, limit: int = SCREEN_HITS) -> tuple[int, ...]:
    """Indices of at most `limit` hits spread evenly over `count`, first and last included."""
    if count <= limit:
        return tuple(range(count))
    return tuple(int(i) for i in np.unique(np.round(np.linspace(0, count - 1, limit))))


@dataclass(frozen=True)
class Screen:
    """One candidate screened at a model: the chi^2 it could remove, and where to refit it."""

    effect: str
    chi2_gain: float
    """Predicted fall of chi^2 from adding the candidate (>= 0) [-]."""
    added_parameters: int
    start: ModelTerm | None
    """The refit's start: the probe scaled by the regression (None: mu_drift, or no probe)."""
    mu_shift: float = 0.0
    """The change of the common mu the regression makes with it [-]."""
    mu_per_hit: np.ndarray | None = None
    """mu_drift: each hit's linearised mu [-]."""
    mu_per_hit_stderr: np.ndarray | None = None
    """Their white-noise standard errors [-]."""
    note: str = ''
    detection_limit: float = math.nan
    """The term's size (its `EFFECT_SIZE` parameter, SI, a magnitude) at which it would just
    be named: its response beyond what the nuisance directions take up would then remove
    what `Naming` asks inside the motion windows. Of the least visible probe (Stribeck: the
    probe speed that hides it most; a second mode: the lightest over the band the hits
    excite, `starts.mode_limit_probes`). mu_drift's is a steady change of mu a hit, as a
    fraction of mu [1/hit] (`screen_drift`)."""
    detection_limit_by_frequency: tuple[tuple[float, float], ...] = ()
    """A second mode's limit at each frequency it is taken at, (frequency [Hz], modal mass
    [kg]) from the lowest: `detection_limit` is their least."""


class Linearisation:
    """A model's residuals and its nuisance directions on some of the cropped impacts.

    Built once per model (two model runs per hit, one without fitted starts) and shared by
    every candidate screened at it. hits: which impacts (default all); `scale` is the count
    of all impacts over theirs.

    In a chained session (`ConditionedImpact.follows_previous`) a change moves every hit's
    rest, and so the start of the hit after it: the directions of a term and of the common
    mu are taken along the chain (`_along_chain`), each hit from where the changed run of
    the hit before it came to rest, as the refit's chained model starts it. Most of what a
    direction-dependent friction does to a chained session is there: taken hit by hit from
    fixed starts, its screen predicted 1-25 % of the chi^2 its refit then removed, too
    little to be refitted at all in some sessions. (Each hit's own mu, under mu_drift, is
    still taken hit by hit: a local direction of its hit.)
    """

    def __init__(
        self,
        impacts: Sequence[ConditionedImpact],
        model: SessionModel,
        fit_initial_position: bool,
        hits: Sequence[int] | None = None,
    ) -> None:
        self.hits = tuple(range(len(impacts)) if hits is None else hits)
        self.scale = len(impacts) / len(self.hits)
        self.impacts = tuple(impacts[i] for i in self.hits)
        self.model = model
        self.residuals = tuple(model.residuals_m_s[i] for i in self.hits)
        self.velocities = [
            impact.velocity_m_s - residual
            for impact, residual in zip(self.impacts, self.residuals, strict=True)
        ]
        mus = model.mus
        rig = model.rig
        position_scale = max(float(np.mean(mus)), 0.01) * rig.normal_force_n
        position_scale /= rig.stiffness_n_per_m

        def columns(place: int) -> tuple[np.ndarray, list[np.ndarray]]:
            hit = self.hits[place]
            step = RELATIVE_STEP * mus[hit]
            mu_column = self._difference(place, step, mu=mus[hit] + step)
            if not fit_initial_position:
                return mu_column, []
            x0 = model.positions_m[hit]
            step = RELATIVE_STEP * max(abs(x0), position_scale)
            return mu_column, [self._difference(place, step, x0_m=x0 + step)]

        made = thread_map(columns, range(len(self.hits)))
        self.mu_columns = [mu_column for mu_column, _ in made]
        self.position_columns = [position for _, position in made]
        self.chained = any(impact.follows_previous for impact in impacts[1 : max(self.hits) + 1])
        self.common_mu_columns = self.mu_columns
        """The common mu's direction: along the chain in a chained session (`_along_chain`)."""
        if self.chained:
            self._chain = tuple(impacts[: max(self.hits) + 1])
            self._rests_m = model.rests_m(self._chain)
            if MU_DRIFT not in model.effects:
                step = RELATIVE_STEP * float(mus[0])
                self.common_mu_columns = [
                    moved / step
                    for moved in self._along_chain(lambda index: {'mu': mus[index] + step})
                ]

    def _difference(self, place: int, step: float, **change) -> np.ndarray:
        impact = self.impacts[place]
        moved = self.model.velocity(
            self.hits[place], impact.force_n, impact.sample_rate_hz, **change
        )
        return (moved - self.velocities[place]) / step

    def _along_chain(self, change: Callable[[int], dict]) -> list[np.ndarray]:
        """The change of each screened hit's velocity when every hit's run changes [m/s].

        change(index): the changed arguments of hit `index`'s run (`SessionModel.run`); the
        hits run in order, each that follows the one before from where that one's changed run
        came to rest (`SessionModel.moved_along_chain`).
        """
        moved = self.model.moved_along_chain(
            self._chain, self._rests_m, {index: change(index) for index in range(len(self._chain))}
        )
        return [
            moved[hit] - velocity for hit, velocity in zip(self.hits, self.velocities, strict=True)
        ]

    def responses(self, term: ModelTerm) -> list[np.ndarray]:
        """Change of each screened hit's velocity when the term is added [m/s].

        Hit by hit (`response`), or along the chain of a chained session for a term that
        moves the rig's rest (an offset and a second mode leave the friction oscillator's
        motion alone).
        """
        if self.chained and term.name not in ('velocity_offset', 'second_mode'):
            effects = (*self.model.terms, term)
            return self._along_chain(lambda _index: {'effects': effects})
        return thread_map(lambda place: self.response(place, term), range(len(self.impacts)))

    def response(self, place: int, term: ModelTerm) -> np.ndarray:
        """Change of the velocity of the place-th screened hit when the term is added [m/s].

        An offset adds itself. A second mode is linear and decoupled from the friction
        oscillator, so its share of the vibrometer's reading is the same whatever the
        oscillator does (`model.mode_velocity`): driven by the hit's force as the model
        scales it, delayed as the model delays it.
        """
        impact = self.impacts[place]
        if term.name == 'velocity_offset':
            return np.full(impact.force_n.size, term.offset_m_s)
        index = self.hits[place]
        if term.name == 'second_mode':
            model = self.model
            delay = model_spec(model.rig, float(model.mus[index]), model.terms).delay_s
            force = impact.force_n * model.impulse_scales[index]
            return mode_velocity(force, impact.sample_rate_hz, term, delay)
        moved = self.model.velocity(
            index, impact.force_n, impact.sample_rate_hz, effects=(*self.model.terms, term)
        )
        return moved - self.velocities[place]

    def nuisance(self) -> tuple[list[list[np.ndarray]], list[list[np.ndarray]]]:
        """(global, local) columns of each hit: mu global unless mu already drifts."""
        if MU_DRIFT in self.model.effects:
            return [[] for _ in self.impacts], [
                [mu, *positions]
                for mu, positions in zip(self.mu_columns, self.position_columns, strict=True)
            ]
        return [[mu] for mu in self.common_mu_columns], self.position_columns


class Fall(NamedTuple):
    """What `chi2_fall` finds: the fall and both solutions."""

    chi2: float
    """The fall of sum |r|^2 [the residuals' unit squared]."""
    shared: np.ndarray
    """The global parameters' solution."""
    local: list[np.ndarray]
    """Each hit's own parameters' solution."""


class Naming(NamedTuple):
    """What naming an effect asks, for a screen to state the size that meets it."""

    m2_s2: float
    """The squared velocity misfit an effect must remove inside the motion windows, summed
    over every hit [m^2/s^2]."""
    windows: Sequence[slice]
    """Every hit's motion window, in session order: where the gaps are judged."""


def chi2_fall(
    residuals: Sequence[np.ndarray],
    global_columns: Sequence[Sequence[np.ndarray]],
    local_columns: Sequence[Sequence[np.ndarray]],
) -> Fall:
    """Least squares of each r_i on sum_g a_g G_gi + sum_l c_il L_il: its `Fall`.

    G: per hit, the columns of the parameters shared by every hit (the same count each); L:
    per hit, its own. The local parameters are eliminated hit by hit, the global ones solved
    from the summed reduced normal equations; the fall is r^T C (C^T C)^-1 C^T r, summed.
    """
    p = len(global_columns[0]) if global_columns else 0
    reduced = np.zeros((p, p))
    right = np.zeros(p)
    fall = 0.0
    kept = []
    for residual, shared, own in zip(residuals, global_columns, local_columns, strict=True):
        columns = np.array([*shared, *own]) if (shared or own) else np.empty((0, residual.size))
        if columns.shape[0] == 0:
            kept.append(None)
            continue
        gram = np.atleast_2d(inner(columns, columns))
        rhs = np.atleast_1d(inner(columns, residual))
        local_gram, local_rhs = gram[p:, p:], rhs[p:]
        cross = gram[p:, :p]
        inverse = _psd_inverse(local_gram) if local_gram.size else np.zeros((0, 0))
        reduced += gram[:p, :p] - cross.T @ inverse @ cross
        right += rhs[:p] - cross.T @ inverse @ local_rhs
        fall += float(local_rhs @ inverse @ local_rhs)
        kept.append((inverse, cross, local_rhs))
    shared_solution = _psd_inverse(reduced) @ right if p else np.zeros(0)
    fall += float(right @ shared_solution)
    local_solution = [
        np.zeros(0) if item is None else item[0] @ (item[2] - item[1] @ shared_solution)
        for item in kept
    ]
    return Fall(fall, shared_solution, local_solution)


def _psd_inverse(matrix: np.ndarray) -> np.ndarray:
    """Pseudo-inverse of a positive semi-definite matrix in unit-diagonal scaling.

    The columns differ by many orders of magnitude (a velocity per unit mu against one per
    metre of start), so the matrix is scaled to unit diagonal first; a zero column stays out.
    """
    diagonal = np.sqrt(np.clip(np.diag(matrix), 0.0, None))
    scale = np.where(diagonal > 0.0, diagonal, 1.0)
    inverse = np.linalg.pinv(matrix / np.outer(scale, scale), hermitian=True)
    return inverse / np.outer(scale, scale)


def screen_term(
    effect: str,
    probes: Sequence[ModelTerm],
    linear: Linearisation,
    noise_std_m_s: float,
    naming: Naming | None = None,
    limit_probes: Sequence[ModelTerm] | None = None,
    ranges: Mapping[str, tuple[float, float]] | None = None,
) -> Screen:
    """The best of the probes of one term: its predicted chi^2 gain and the refit's start.

    The probe's size parameter (`EFFECT_SIZE`) is scaled by the regression coefficient (the
    second mode's mass divided by it), and clipped into the term's bounds (ranges, the
    session's `physical_ranges`, where given). A coefficient of
    the wrong sign for a non-negative size is no gain: the data ask for the opposite effect,
    which the term does not express.

    naming: what naming an effect asks; with it, the screen also gives the term's
    `detection_limit`, the least visible of its limit_probes' (default: the probes).
    """
    cls = MODEL_TERMS[effect]
    shared, own = linear.nuisance()
    before = chi2_fall(linear.residuals, shared, own).chi2
    best = Screen(effect, 0.0, len(cls.parameters), None, note='no probe')
    limits = []
    for probe in probes:
        responses = linear.responses(probe)
        if not any(np.any(response) for response in responses):
            continue
        if not all(np.all(np.isfinite(response)) for response in responses):
            # A softening probe beyond its turning point escapes (the model's run is not
            # finite): it linearises nothing, and the term's other probes still screen it.
            if best.start is None:
                best = replace(best, note='a probe whose model run is not finite')
            continue
        fall, solution, _ = chi2_fall(
            linear.residuals,
            [[response, *columns] for response, columns in zip(responses, shared, strict=True)],
            own,
        )
        if naming is not None and limit_probes is None:
            limits.append(_limit(probe, responses, shared, own, linear, naming))
        gain = linear.scale * max(fall - before, 0.0) / noise_std_m_s**2
        start, note = _scaled(probe, float(solution[0]), ranges)
        if start is None:
            gain = 0.0
        shift = float(solution[1]) if solution.size > 1 else 0.0
        if gain > best.chi2_gain or best.start is None:
            best = Screen(effect, gain, len(cls.parameters), start or probe, shift, note=note)
    curve = ()
    if naming is not None and limit_probes is not None:
        limits = [
            _limit(probe, linear.responses(probe), shared, own, linear, naming)
            for probe in limit_probes
        ]
        if effect == 'second_mode':
            curve = tuple(
                (p.frequency_hz, limit) for p, limit in zip(limit_probes, limits, strict=True)
            )
    if limits:
        _, inverse = EFFECT_SIZE[effect]
        limit = min(limits) if inverse else max(limits)
        best = replace(best, detection_limit=limit, detection_limit_by_frequency=curve)
    return best


def _limit(
    probe: ModelTerm,
    responses: Sequence[np.ndarray],
    shared: Sequence[Sequence[np.ndarray]],
    own: Sequence[Sequence[np.ndarray]],
    linear: Linearisation,
    naming: Naming,
) -> float:
    """The size of the probe's term at which its responses would meet naming (`_named_from`)."""
    name, inverse = EFFECT_SIZE[probe.name]
    inside = _own_inside(responses, shared, own, linear, naming.windows)
    return _named_from(abs(getattr(probe, name)), inverse, inside, naming.m2_s2)


def _own_inside(
    directions: Sequence[np.ndarray],
    shared: Sequence[Sequence[np.ndarray]],
    own: Sequence[Sequence[np.ndarray]],
    linear: Linearisation,
    windows: Sequence[slice],
) -> float:
    """What the nuisance cannot take of a direction, its squared norm inside the motion windows.

    Over every hit (scaled from the screened ones) [the direction's unit squared].

    A refit moves mu and the starts with the term, so only the direction's part beyond them
    is the term's own; and naming is judged on the gap over the motion, so only its part
    there counts (a velocity offset is as large at rest as in motion, a cubic spring is not).
    """
    taken = chi2_fall(directions, shared, own)
    inside = 0.0
    for place, (direction, columns, locals_, local) in enumerate(
        zip(directions, shared, own, taken.local, strict=True)
    ):
        rest = direction.copy()
        for coefficient, column in zip((*taken.shared, *local), (*columns, *locals_), strict=True):
            rest -= coefficient * column
        window = rest[windows[linear.hits[place]]]
        inside += inner(window, window)
    return linear.scale * inside


def _named_from(size: float, inverse: bool, own_m2_s2: float, naming_m2_s2: float) -> float:
    """The size at which a direction of this size and own energy would remove naming_m2_s2.

    The response is linear in the size (inverse: in 1 / size). NaN without naming_m2_s2;
    inf (0 for an inverse size) when nothing of the direction is its own.
    """
    if not naming_m2_s2 > 0.0:
        return math.nan
    if own_m2_s2 <= 0.0:
        return 0.0 if inverse else math.inf
    ratio = math.sqrt(naming_m2_s2 / own_m2_s2)
    return size / ratio if inverse else size * ratio


def _scaled(
    probe: ModelTerm,
    coefficient: float,
    ranges: Mapping[str, tuple[float, float]] | None = None,
) -> tuple[ModelTerm | None, str]:
    """The probe with its size scaled by the coefficient, in bounds; None if it cannot be."""
    name, inverse = EFFECT_SIZE[probe.name]
    index = [p.name for p in probe.parameters].index(name)
    parameter = probe.parameters[index]
    size = getattr(probe, name)
    if inverse:
        if coefficient <= 0.0:
            return None, f'the residual asks for a negative {name}'
        value = size / coefficient
    else:
        value = size * coefficient
    if parameter.domain != 'real' and value <= 0.0:
        return None, f'the residual asks for {name} < 0, which the term does not express'
    low, high = probe.bounds(ranges)
    return replace(probe, **{name: float(np.clip(value, low[index], high[index]))}), ''


def screen_drift(
    linear: Linearisation, noise_std_m_s: float, naming: Naming | None = None
) -> Screen:
    """mu_drift: the chi^2 gain of one mu per hit over one for all, and the per-hit mu.

    The linearisation must hold every hit. naming, as `screen_term`'s: with it, the
    screen's `detection_limit` is the steady change of mu from hit to hit, as a fraction of
    mu [1/hit], whose response beyond the common mu and the starts would remove it (what
    the hits' own mu must show besides is the workflow's: `_detectable_drift`).
    """
    if linear.scale != 1.0:
        raise BadInputError('mu_drift is screened on every hit')
    shared, own = linear.nuisance()
    before = chi2_fall(linear.residuals, shared, own).chi2
    per_hit = [
        [mu, *positions]
        for mu, positions in zip(linear.mu_columns, linear.position_columns, strict=True)
    ]
    fall, _, local = chi2_fall(linear.residuals, [[] for _ in per_hit], per_hit)
    mus = linear.model.mus + np.array([solution[0] for solution in local])
    errors = np.array(
        [
            noise_std_m_s / math.sqrt(max(inner(column, column), np.finfo(float).tiny))
            for column in linear.mu_columns
        ]
    )
    gain = max(fall - before, 0.0) / noise_std_m_s**2
    limit = math.nan
    if naming is not None:
        # mu_i = mu (1 + s i): a change s a hit moves hit i's mu by mu i s; the common mu
        # takes up its mean, the starts what they can.
        steady = [
            float(linear.model.mus[hit]) * hit * column
            for hit, column in zip(linear.hits, linear.mu_columns, strict=True)
        ]
        inside = _own_inside(steady, shared, own, linear, naming.windows)
        limit = _named_from(1.0, False, inside, naming.m2_s2)
    return Screen(
        MU_DRIFT,
        gain,
        len(per_hit) - 1,
        None,
        mu_per_hit=mus,
        mu_per_hit_stderr=errors,
        detection_limit=limit,
    )
