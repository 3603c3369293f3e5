"""Diagnosis cases from the independent lab-data generator (`worlds`): the effect, drawn at random.

Each kind is one physical situation: an effect the diagnosis has a term for (drawn through
worlds' own laws and effects), a pair of them, friction running in over eight hits, a law
outside the vocabulary (two speed regimes, a sinusoidal wear track, a sharp wear patch), or a
clean contact, all through worlds' default DAQ chain (anti-alias filters, hum, drift, ADC).
Three-hit kinds are isolated hits of the rig at rest at its centre, at random paper levels
(the diagnosis takes each start at x = 0); eight-hit kinds are worlds' continuous recordings,
where each hit finds the rig where friction left it (the diagnosis fits each start). Sizes are
drawn from ranges that put the discrepancy after the base fit at about 1-5 times the velocity
noise; the benchmark reports the realised size (the base model's excess over the noise).

Asymmetric friction is only drawn in isolated hits: from velocity alone it shows only in how
the first half cycle relates to where the hit found the rig (every later half cycle loses
(mu+ + mu-) N / k either way), which a fitted start absorbs.
"""

import numpy as np
import worlds

VOCABULARY_KINDS = (
    'viscous_damping',
    'stribeck',
    'asymmetric_friction',
    'cubic_stiffness',
    'second_mode',
    'velocity_offset',
    'sensor_delay',
)
OUTSIDE_KINDS = ('speed_regimes', 'wear_track', 'wear_patch')
DRIFT_HITS = 8
MU_RANGE = (0.08, 0.16)


def _log_uniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(np.exp(rng.uniform(np.log(low), np.log(high))))


def _sign(rng: np.random.Generator) -> float:
    return float(rng.choice((-1.0, 1.0)))


def _apply(kind: str, friction, effects: list, mu: float, rng: np.random.Generator):
    """The world's friction law and effects with one more effect of this kind."""
    if kind == 'viscous_damping':
        effects.append(worlds.ViscousDamping(rng.uniform(0.1, 0.35)))
    elif kind == 'stribeck':
        friction = worlds.Stribeck(
            friction, rng.uniform(0.02, 0.06), _log_uniform(rng, 1.5e-3, 6e-3)
        )
    elif kind == 'asymmetric_friction':
        half = 0.5 * mu * rng.uniform(0.08, 0.2) * _sign(rng)
        friction = worlds.AsymmetricCoulomb(mu + half, mu - half)
    elif kind == 'cubic_stiffness':
        effects.append(worlds.CubicStiffness(_sign(rng) * rng.uniform(2e4, 8e4)))
    elif kind == 'second_mode':
        effects.append(
            worlds.SecondMode(
                _log_uniform(rng, 15.0, 300.0),
                _log_uniform(rng, 3e-3, 3e-2),
                _log_uniform(rng, 300.0, 1500.0),
            )
        )
    elif kind == 'velocity_offset':
        effects.append(worlds.VelocityOffset(_sign(rng) * rng.uniform(1e-4, 4e-4)))
    elif kind == 'sensor_delay':
        effects.append(worlds.VibrometerLag(rng.uniform(1e-4, 3e-4)))
    elif kind == 'speed_regimes':
        # Friction rising above the switch: falling, it is what the Stribeck term expresses.
        factor = 1.0 + rng.uniform(0.03, 0.08)
        friction = worlds.SpeedRegimes(
            friction, worlds.Coulomb(mu * factor), rng.uniform(0.02, 0.06), 0.004
        )
    elif kind == 'wear_track':
        friction = worlds.WearTrack(
            friction, rng.uniform(0.05, 0.15), rng.uniform(4e-3, 10e-3), rng.uniform(0, 2 * np.pi)
        )
    elif kind == 'wear_patch':
        start = rng.uniform(-3e-3, 1e-3)
        friction = worlds.WearPatch(
            friction,
            start,
            start + rng.uniform(1.5e-3, 3e-3),
            1.0 + _sign(rng) * rng.uniform(0.08, 0.2),
        )
    else:
        raise ValueError(f'unknown kind {kind!r}')
    return friction


def world_case(kind: str, rng: np.random.Generator):
    """(records, hidden effects in the diagnosis's names, whether starts are to be fitted).

    kind: a vocabulary term, 'pair' (two distinct terms), 'mu_drift' (run-in over eight
    hits), one of OUTSIDE_KINDS, or 'none' / 'none8' (clean, three or eight hits).
    """
    mu = float(rng.uniform(*MU_RANGE))
    friction, effects, hidden, run_in, hits = worlds.Coulomb(mu), [], (), None, 3
    if kind in VOCABULARY_KINDS or kind in OUTSIDE_KINDS:
        friction = _apply(kind, friction, effects, mu, rng)
        hidden = (kind,)
    elif kind == 'pair':
        pair = tuple(str(k) for k in rng.choice(VOCABULARY_KINDS, size=2, replace=False))
        if 'asymmetric_friction' in pair and 'stribeck' in pair:
            pair = ('asymmetric_friction', 'stribeck')  # the asymmetric base first, wrapped
        for name in pair:
            friction = _apply(name, friction, effects, mu, rng)
        hidden = pair
    elif kind == 'mu_drift':
        start = 1.0 + _sign(rng) * rng.uniform(0.02, 0.06)
        run_in = worlds.RunIn(start, rng.uniform(4.0, 12.0))
        hits = DRIFT_HITS
        hidden = ('mu_drift',)
    elif kind == 'none8':
        hits = DRIFT_HITS
    elif kind != 'none':
        raise ValueError(f'unknown kind {kind!r}')
    world = worlds.World(friction=friction, effects=tuple(effects))
    if hits == DRIFT_HITS:
        return worlds.record_session(world, rng, hits=hits, run_in=run_in).records(), hidden, True
    levels = rng.choice(('low', 'medium', 'high'), size=hits)
    records = [
        worlds.impact_record(
            world, rng, pulse=worlds.random_pulse(rng, str(level)), start_position_m=0.0
        )
        for level in levels
    ]
    return records, hidden, False
