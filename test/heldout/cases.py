"""Diagnosis cases from the held-out generators: one kind of session, its size drawn at random.

Kinds (`kinds_of` a world): each effect the diagnosis has a name for, hidden alone; `pair` (two
distinct ones); `mu_drift` (mu changing 4-7 % a hit over three hits); `wear_track` (friction
varying along the track: outside the vocabulary, the right answer is 'unexplained'); `none` (the
plain rig). Three hits a session, one at each paper level in random order, every one from rest
at the centre, except the `CHAINED_KINDS`: `asymmetric_chained` and `none_chained` are one
continuous session each, the first hit from rest at the centre and each later one where the one
before it came to rest (the diagnosis chains the starts: `STARTS`). Sizes are drawn from ranges
that leave a misfit of about 1-5 velocity-noise deviations after the base fit on the swings of
the `events` world, the same ranges on every world: where a world's hammer swings the rig less
(the stiff tips of `newmark` and `karnopp`), a cubic spring drawn here leaves a median of
0.5-4x the noise, some under the diagnosis's floor.
"""

import numpy as np

from heldout.analytic import ANALYTIC, AnalyticWorld, re_centred
from heldout.bristle import BRISTLE, BristleWorld
from heldout.ivp import IVP, IvpWorld
from heldout.karnopp import KARNOPP, KarnoppWorld
from heldout.lab import EVENTS, STEPS, Effects, World, session
from heldout.moreau import MOREAU, MoreauWorld
from heldout.moreau import re_centred as moreau_re_centred
from heldout.newmark import NEWMARK, NewmarkWorld

VOCABULARY_KINDS = (
    'viscous_damping',
    'stribeck',
    'asymmetric_friction',
    'cubic_stiffness',
    'second_mode',
    'velocity_offset',
    'sensor_delay',
)
CHAINED_KINDS = {'asymmetric_chained': 'asymmetric_friction', 'none_chained': 'none'}
"""Kinds made as one continuous session, and the kind of effect each hides."""
KINDS = (*VOCABULARY_KINDS, 'pair', 'mu_drift', 'wear_track', 'none', *CHAINED_KINDS)
CENTRE, FITTED, CHAINED = 'centre', 'fitted', 'chained'
STARTS = {kind: CHAINED if kind in CHAINED_KINDS else CENTRE for kind in KINDS}
"""Where the diagnosis is to start each kind's hits: at the centre, or chained (`fmm_ros`'s
`FitSpec.starts`, spelled here again: this package imports nothing of the product). The
`analytic`, `bristle`, `newmark` and `karnopp` worlds start isolated hits from rest in the
friction band, and the `moreau` world each hit where the one before left the rig, so their hits
are FITTED unless the session is re-centred (`analytic.re_centred`, `moreau.re_centred`)."""
VIBROMETER_KINDS = ('velocity_offset',)
"""Effects of a vibrometer's own, which a world measured by an accelerometer cannot hide."""


def kinds_of(world: World) -> tuple[str, ...]:
    """The kinds of session a world is swept over.

    No vibrometer effect under an accelerometer, and no chained session there (chained
    starts are measured on vibrometer worlds only).
    """
    if world.sensor == 'velocity':
        return KINDS
    return tuple(k for k in KINDS if k not in VIBROMETER_KINDS and k not in CHAINED_KINDS)


MU_RANGE = (0.08, 0.16)


def _log_uniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(np.exp(rng.uniform(np.log(low), np.log(high))))


def _sign(rng: np.random.Generator) -> float:
    return float(rng.choice((-1.0, 1.0)))


def effect_fields(kind: str, mu: float, rng: np.random.Generator) -> dict:
    """The Effects fields of one hidden effect of a kind, its size drawn."""
    if kind == 'viscous_damping':
        return {'added_damping_n_s_per_m': rng.uniform(0.12, 0.4)}
    if kind == 'stribeck':
        return {
            'static_excess': rng.uniform(0.02, 0.06),
            'stribeck_speed_m_s': _log_uniform(rng, 1.5e-3, 6e-3),
        }
    if kind == 'asymmetric_friction':
        return {'asymmetry': _sign(rng) * mu * rng.uniform(0.1, 0.25)}
    if kind == 'cubic_stiffness':
        return {'cubic_n_per_m3': _sign(rng) * rng.uniform(3e4, 9e4)}
    if kind == 'second_mode':
        return {
            'mode_hz': _log_uniform(rng, 15.0, 300.0),
            'mode_damping_ratio': _log_uniform(rng, 3e-3, 3e-2),
            'mode_mass_kg': _log_uniform(rng, 300.0, 1500.0),
        }
    if kind == 'velocity_offset':
        return {'velocity_offset_m_s': _sign(rng) * rng.uniform(1.2e-4, 4e-4)}
    if kind == 'sensor_delay':
        return {'lag_s': rng.uniform(1e-4, 3e-4)}
    if kind == 'mu_drift':
        return {'mu_step': _sign(rng) * rng.uniform(0.04, 0.07)}
    if kind == 'wear_track':
        return {
            'track_amplitude': rng.uniform(0.08, 0.15),
            'track_wavelength_m': rng.uniform(4e-3, 10e-3),
            'track_phase': rng.uniform(0.0, 2 * np.pi),
        }
    raise ValueError(f'unknown kind {kind!r}')


AnyWorld = (
    World | IvpWorld | AnalyticWorld | MoreauWorld | BristleWorld | NewmarkWorld | KarnoppWorld
)
"""Any of the held-out generators' worlds."""

WORLDS: dict[str, AnyWorld] = {
    'events': EVENTS,
    'steps': STEPS,
    'ivp': IVP,
    'analytic': ANALYTIC,
    'moreau': MOREAU,
    'bristle': BRISTLE,
    'newmark': NEWMARK,
    'karnopp': KARNOPP,
}
"""Every world the sessions are drawn from, by its name in `heldout.ROLES`."""


def drawn_effects(
    world: AnyWorld, kind: str, rng: np.random.Generator
) -> tuple[float, tuple[str, ...], Effects]:
    """(mu, hidden effects in the diagnosis's names, Effects) of a kind's session.

    The first draws `case` makes: a generator in the same state gives the session's truth.
    """
    kind = CHAINED_KINDS.get(kind, kind)
    mu = float(rng.uniform(*MU_RANGE))
    if kind == 'none':
        hidden, fields = (), {}
    elif kind == 'pair':
        vocabulary = [k for k in VOCABULARY_KINDS if k in kinds_of(world)]
        hidden = tuple(str(k) for k in rng.choice(vocabulary, size=2, replace=False))
        fields = {}
        for name in hidden:
            fields.update(effect_fields(name, mu, rng))
    else:
        hidden = (kind,)
        fields = effect_fields(kind, mu, rng)
    return mu, hidden, Effects(**fields)


def case(world: AnyWorld, kind: str, rng: np.random.Generator):
    """(records, hidden effects in the diagnosis's names, where the diagnosis starts the hits).

    Where it starts them: CENTRE, FITTED (an `analytic`, `bristle`, `newmark` or `karnopp`
    session's hits from rest in the friction band, a `moreau` session's from where the hit
    before left the rig) or CHAINED.
    """
    chained = kind in CHAINED_KINDS
    mu, hidden, effects = drawn_effects(world, kind, rng)
    kind = CHAINED_KINDS.get(kind, kind)
    levels = rng.permutation((450.0, 1000.0, 1450.0))
    records, starts = session_of(world, effects, mu, rng, levels, chained=chained)
    return records, () if kind == 'wear_track' else hidden, starts


def session_of(
    world: AnyWorld,
    effects: Effects,
    mu: float,
    rng: np.random.Generator,
    levels: np.ndarray,
    *,
    chained: bool = False,
):
    """(records, where the diagnosis starts the hits) of one session of any world (`case`)."""
    starts = CHAINED if chained else CENTRE
    if isinstance(world, AnalyticWorld):
        records = world.session(effects, mu, rng, levels, chained=chained)
        starts = starts if chained or re_centred(effects) else FITTED
    elif isinstance(world, MoreauWorld):
        records = world.session(effects, mu, rng, levels, chained=chained)
        starts = starts if chained or moreau_re_centred(effects) else FITTED
    elif isinstance(world, BristleWorld | NewmarkWorld | KarnoppWorld):
        centred = re_centred(effects)
        records = world.session(effects, mu, rng, levels, chained=chained, centred=centred)
        starts = starts if chained or centred else FITTED
    elif isinstance(world, IvpWorld):
        records = world.session(effects, mu, rng, levels, chained=chained)
    else:
        records = session(world, effects, mu, rng, levels, chained=chained)
    return records, starts
