"""The independent lab-data generator (test/worlds): its physics, its DAQ chain, its sessions.

The generator is what claims about real data are tested against, so it is checked here
against things outside itself: a brute-force tiny-step integration, textbook results of the
Coulomb oscillator, energy balances, quadrature of the pulses, the analog filters' responses
and the product's CSV reader (the only use of the product in this file).
"""

import ast
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numba
import numpy as np
import pytest
import scipy.integrate
import scipy.signal
import scipy.special
from worlds import (
    AnalogFilter,
    AsymmetricCoulomb,
    ChannelChain,
    ContinuousSignal,
    Coulomb,
    CubicStiffness,
    DaqChain,
    DeadVibrometer,
    DoubleHit,
    DroppedSamples,
    DwellStrengthening,
    ForceClip,
    HalfSine,
    NonFiniteBurst,
    PlacedPulse,
    Plant,
    PlantState,
    RunIn,
    SecondMode,
    SkewedPulse,
    SpeedRegimes,
    StaticFriction,
    Stribeck,
    VelocityOffset,
    VibrometerLag,
    VibrometerSaturation,
    ViscousDamping,
    WearPatch,
    WearTrack,
    World,
    analog_channel,
    digitise,
    impact_record,
    linear_response,
    random_damage,
    random_pulse,
    record_session,
    simulate_motion,
    write_record_csv,
)
from worlds.damage import DAMAGE_KINDS
from worlds.pulses import PAPER_LEVELS

WORLDS_DIR = Path(__file__).resolve().parent / 'worlds'
RATE_HZ = 10_000.0
QUIET = DaqChain(
    force=ChannelChain(anti_alias=None, full_scale=5000.0, adc_bits=32),
    velocity=ChannelChain(anti_alias=None, full_scale=1.0, adc_bits=32),
)
"""No filter, interference or noise, and 32-bit steps: the continuous signals, sampled."""
MEDIUM = HalfSine.for_impulse(1000.0, 1.42)


def _band_m(world: World, mu: float) -> float:
    plant = world.mechanics
    return mu * plant.normal_force_n / plant.stiffness_n_per_m


# --- independence --------------------------------------------------------------------------


def test_worlds_imports_nothing_of_the_product():
    for path in sorted(WORLDS_DIR.glob('*.py')):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or '']
            else:
                continue
            assert not any(name.split('.')[0] == 'fmm_ros' for name in names), (
                f'{path.name} imports {names}: the generator must stay independent'
            )
        assert 'import_module' not in path.read_text() and '__import__' not in path.read_text()


@pytest.mark.slow
def test_making_a_record_loads_no_product_module():
    code = (
        'import sys; sys.path.insert(0, sys.argv[1]); import numpy as np, worlds; '
        'worlds.impact_record(worlds.World(), np.random.default_rng(0)); '
        'print(sorted(m for m in sys.modules if m.split(".")[0] == "fmm_ros"))'
    )
    result = subprocess.run(
        [sys.executable, '-c', code, str(WORLDS_DIR.parent)],
        capture_output=True,
        text=True,
        check=True,
    )
    assert result.stdout.strip() == '[]'


# --- friction laws ---------------------------------------------------------------------------


def test_friction_laws_give_their_documented_coefficients():
    base = Coulomb(0.1)
    assert Stribeck(base, 0.03, 2e-3).sliding_mu(-1, 2e-3, 0.0) == pytest.approx(
        0.1 + 0.03 / math.e
    )
    assert Stribeck(base, 0.03, 2e-3).static_mu(1, 0.0, 0.0) == pytest.approx(0.13)
    assert StaticFriction(base, 0.02).static_mu(-1, 0.0, 0.0) == pytest.approx(0.12)
    assert StaticFriction(base, 0.02).sliding_mu(-1, 0.1, 0.0) == 0.1
    asym = AsymmetricCoulomb(0.08, 0.12)
    assert (asym.sliding_mu(1, 0.0, 0), asym.sliding_mu(-1, 0.1, 0), asym.nominal_mu) == (
        0.08,
        0.12,
        pytest.approx(0.1),
    )
    assert list(asym.sliding_mu(np.array([1, -1, 1]), 0.0, 0.0)) == [0.08, 0.12, 0.08]
    track = WearTrack(base, 0.2, 4e-3)
    assert track.sliding_mu(1, 0.1, 1e-3) == pytest.approx(0.12)
    assert track.static_mu(1, 3e-3, 0.0) == pytest.approx(0.08)
    patch = WearPatch(base, 1e-3, 2e-3, 1.5)
    assert list(patch.sliding_mu(1, 0.1, np.array([0.5e-3, 1e-3, 1.999e-3, 2e-3]))) == (
        pytest.approx([0.1, 0.15, 0.15, 0.1])
    )
    assert patch.position_breaks_m == (1e-3, 2e-3)
    dwell = DwellStrengthening(base, 0.01, 0.1)
    assert dwell.static_mu(1, 0.0, 0.0) == pytest.approx(0.1)
    assert dwell.static_mu(1, 0.0, 0.1 * (math.e - 1)) == pytest.approx(0.11)
    regimes = SpeedRegimes(Coulomb(0.12), Coulomb(0.08), 0.05, 0.002)
    assert regimes.sliding_mu(1, 0.01, 0) == pytest.approx(0.12, abs=1e-9)
    assert regimes.sliding_mu(1, 0.05, 0) == pytest.approx(0.10)
    assert regimes.sliding_mu(-1, 0.2, 0) == pytest.approx(0.08, abs=1e-9)
    # Composed laws scale whole (a run-in factor), and only Coulomb-like laws allow the
    # closed form.
    law = WearTrack(Stribeck(AsymmetricCoulomb(0.08, 0.12), 0.02, 1e-3), 0.1, 5e-3)
    assert law.scaled(2.0).sliding_mu(-1, 1e-3, 2e-3) == pytest.approx(
        2 * law.sliding_mu(-1, 1e-3, 2e-3)
    )
    assert law.nominal_mu == pytest.approx(0.1)
    assert [x.constant_sliding_mu(1) for x in (base, asym, StaticFriction(base), dwell)] == [
        0.1,
        0.08,
        0.1,
        0.1,
    ]
    assert [x.constant_sliding_mu(1) for x in (track, patch, regimes, Stribeck(base))] == [None] * 4
    for bad in (
        lambda: Coulomb(-0.1),
        lambda: WearTrack(base, 1.0),
        lambda: WearPatch(base, 2e-3, 1e-3),
        lambda: Stribeck(base, 0.01, 0.0),
    ):
        with pytest.raises(ValueError):
            bad()


# --- the plant -------------------------------------------------------------------------------


def _events(trajectory):
    return np.array([(e.time_s, e.position_m) for e in trajectory.events])


@pytest.mark.parametrize(
    'world',
    [
        World(),
        World(friction=AsymmetricCoulomb(0.09, 0.14)),
        World(friction=StaticFriction(Coulomb(0.1), 0.04)),
        World(friction=DwellStrengthening(Coulomb(0.1), 0.02, 0.1)),
        World(effects=(ViscousDamping(3.0),)),
    ],
    ids=['coulomb', 'asymmetric', 'static', 'dwell', 'viscous'],
)
def test_closed_form_path_matches_the_general_path(world):
    pulses = [PlacedPulse(MEDIUM, 0.0123), PlacedPulse(replace(MEDIUM, peak_force_n=600.0), 1.3)]
    runs = [
        simulate_motion(world, pulses, 0.0, 12.0, PlantState(3e-4, 0.0, -30.0), method=m)
        for m in ('auto', 'general')
    ]
    (fast, fast_end), (general, general_end) = runs
    assert [e.kind for e in fast.events] == [e.kind for e in general.events]
    assert len(fast.reversals()) > 10
    assert np.abs(_events(fast) - _events(general)).max() < 1e-9
    grid = np.linspace(0.0, 12.0, 200_001)
    assert np.abs(fast.evaluate(grid)[1] - general.evaluate(grid)[1]).max() < 1e-9
    assert fast_end.position_m == pytest.approx(general_end.position_m, abs=1e-11)


@numba.njit(cache=False)
def _half_sine_n(t, peak, start, contact):
    if start <= t <= start + contact:
        return peak * math.sin(math.pi * (t - start) / contact)
    return 0.0


@numba.njit(cache=False)
def _brute_force(constants, pulse, x0, stop_s, h):
    """Classical RK4 at a fixed tiny step; a velocity sign change inside a step is located by
    linear interpolation (Hermite for the position), then the stick rule is applied."""
    m, c, k, k3, normal, mu, dmu, vs = constants
    peak, start, contact = pulse
    t, x, v, s = 0.0, x0, 0.0, 0
    out = np.empty((1000, 2))
    n = 0
    limit = normal * (mu + dmu)
    while t < stop_s and n < 1000:
        if s == 0:
            if abs(_half_sine_n(t + h, peak, start, contact) - k * x - k3 * x**3) > limit:
                lo, hi = t, t + h
                for _ in range(60):
                    mid = 0.5 * (lo + hi)
                    if abs(_half_sine_n(mid, peak, start, contact) - k * x - k3 * x**3) > limit:
                        hi = mid
                    else:
                        lo = mid
                t = hi
                s = 1 if _half_sine_n(t, peak, start, contact) - k * x - k3 * x**3 > 0 else -1
            else:
                t += h
            continue
        xs = np.empty(4)
        vs_ = np.empty(4)
        acc = np.empty(4)
        for stage, (dt, weight) in enumerate(((0.0, 0.0), (0.5, 0.5), (0.5, 0.5), (1.0, 1.0))):
            xi = x if stage == 0 else x + weight * h * vs_[stage - 1]
            vi = v if stage == 0 else v + weight * h * acc[stage - 1]
            xs[stage], vs_[stage] = xi, vi
            friction = s * normal * (mu + dmu * math.exp(-((vi / vs) ** 2)))
            acc[stage] = (
                _half_sine_n(t + dt * h, peak, start, contact)
                - c * vi
                - k * xi
                - k3 * xi**3
                - friction
            ) / m
        xn = x + h / 6.0 * (vs_[0] + 2 * vs_[1] + 2 * vs_[2] + vs_[3])
        vn = v + h / 6.0 * (acc[0] + 2 * acc[1] + 2 * acc[2] + acc[3])
        if s * vn > 0.0:
            t, x, v = t + h, xn, vn
            continue
        u = v / (v - vn)
        x = (
            (2 * u**3 - 3 * u**2 + 1) * x
            + (u**3 - 2 * u**2 + u) * h * v
            + (-2 * u**3 + 3 * u**2) * xn
            + (u**3 - u**2) * h * vn
        )
        t, v = t + u * h, 0.0
        out[n, 0], out[n, 1] = t, x
        n += 1
        net = _half_sine_n(t, peak, start, contact) - k * x - k3 * x**3
        s = 0 if abs(net) <= limit else (1 if net > 0 else -1)
    return out[:n]


@pytest.mark.slow
def test_general_path_matches_a_brute_force_reference():
    """Stribeck friction and a stiffening flexure: no closed form, DOP853 with events against
    fixed-step RK4 at 1 us (its own error: ~4e-9 s, ~3e-10 m at the events)."""
    world = World(friction=Stribeck(Coulomb(0.12), 0.03, 5e-3), effects=(CubicStiffness(3e6),))
    start, x0 = 0.01234, 2e-4
    trajectory, _ = simulate_motion(
        world, [PlacedPulse(MEDIUM, start)], 0.0, 6.0, PlantState(x0), method='auto'
    )
    p = world.mechanics
    reference = _brute_force(
        np.array(
            [
                p.mass_kg,
                p.damping_n_s_per_m,
                p.stiffness_n_per_m,
                p.cubic_stiffness_n_per_m3,
                p.normal_force_n,
                0.12,
                0.03,
                5e-3,
            ]
        ),
        np.array([MEDIUM.peak_force_n, start, MEDIUM.contact_s]),
        x0,
        6.0,
        1e-6,
    )
    ours = np.array([(e.time_s, e.position_m) for e in trajectory.reversals()])
    assert trajectory.events[-1].kind == 'stick' and len(ours) == len(reference) > 8
    assert np.abs(ours[:, 0] - reference[:, 0]).max() < 2e-8
    assert np.abs(ours[:, 1] - reference[:, 1]).max() < 2e-9


def test_coulomb_decay_loses_four_friction_bands_per_cycle():
    """Without viscous damping, each half cycle about the shifted equilibrium +-F/k is a
    mirror image: the amplitude drops by exactly 2 F/k per half cycle, 4 F/k per cycle, and
    the mass stops inside +-F/k (released from 10 mm, as in the paper's Sec. 2)."""
    mu = 0.113
    world = World(plant=Plant(damping_n_s_per_m=0.0), friction=Coulomb(mu))
    band = _band_m(world, mu)
    for method in ('auto', 'general'):
        trajectory, end = simulate_motion(world, [], 0.0, 10.0, PlantState(0.01), method=method)
        assert trajectory.events[0].kind == 'break-away'
        peaks = np.array([e.position_m for e in trajectory.reversals()])
        expected = (0.01 - 2 * band * np.arange(1, peaks.size + 1)) * (-1.0) ** np.arange(
            1, peaks.size + 1
        )
        assert np.abs(peaks - expected).max() < 1e-11
        assert abs(peaks[-1]) <= band < abs(peaks[-2])
        assert peaks.size == math.ceil((0.01 - band) / (2 * band))
        half_period = math.pi * math.sqrt(world.plant.mass_kg / world.plant.stiffness_n_per_m)
        times = [e.time_s for e in trajectory.reversals()]
        assert np.diff(times) == pytest.approx(half_period, rel=1e-9)
        assert end.velocity_m_s == 0.0 and end.stuck_since_s == pytest.approx(times[-1])


@pytest.mark.parametrize(
    'friction',
    [
        Coulomb(0.113),
        StaticFriction(Coulomb(0.09), 0.05),
        AsymmetricCoulomb(0.07, 0.15),
        Stribeck(Coulomb(0.1), 0.03, 3e-3),
    ],
    ids=['coulomb', 'static', 'asymmetric', 'stribeck'],
)
@pytest.mark.slow
def test_rest_positions_lie_inside_the_static_band(friction):
    world = World(friction=friction)
    plant = world.mechanics
    rng = np.random.default_rng(5)
    rests = []
    for _ in range(12):
        x0 = rng.uniform(-1, 1) * world.static_band_m()
        pulse = PlacedPulse(random_pulse(rng), 0.01 + rng.uniform(0, 1e-4))
        trajectory, end = simulate_motion(world, [pulse], 0.0, 8.0, PlantState(x0))
        assert end.stuck_since_s is not None
        x = end.position_m
        holding = plant.normal_force_n * friction.static_mu(-1 if x > 0 else 1, x, 0.0)
        assert plant.stiffness_n_per_m * abs(x) <= holding * (1 + 1e-12)
        # At rest before the hit and after the stop: the continuous motion says so too.
        before = trajectory.evaluate(np.linspace(0.0, 0.0099, 50))
        after = trajectory.evaluate(np.linspace(end.stuck_since_s, 8.0, 50))
        assert np.all(before[0] == x0) and np.all(before[1] == 0)
        assert np.all(after[0] == x) and np.all(after[1] == 0)
        rests.append(x)
    kinetic = _band_m(world, friction.constant_sliding_mu(1) or 0.1)
    if isinstance(friction, StaticFriction):
        # Static above kinetic widens the rest band: some stops land where Coulomb could not.
        assert max(abs(x) for x in rests) > kinetic


def test_breakaway_happens_when_the_net_force_leaves_the_static_band():
    law = DwellStrengthening(Coulomb(0.1), 0.05, 0.1)
    world = World(friction=law)
    plant = world.mechanics
    x0 = 3e-4
    pulse = PlacedPulse(SkewedPulse.for_impulse(450.0, 0.98, 0.3), 0.02)
    times = []
    for rested_s in (0.05, 50.0):
        trajectory, _ = simulate_motion(world, [pulse], 0.0, 3.0, PlantState(x0, 0.0, -rested_s))
        event = trajectory.events[0]
        assert event.kind == 'break-away' and event.position_m == x0
        t = event.time_s
        net = float(pulse.force_n(t)) - plant.stiffness_n_per_m * x0
        limit = plant.normal_force_n * law.static_mu(1, x0, t + rested_s)
        assert net == pytest.approx(limit, abs=1e-9)
        assert float(pulse.force_n(t - 1e-8)) - plant.stiffness_n_per_m * x0 < limit
        times.append(t)
    assert times[1] > times[0]  # a contact left longer holds longer


def _half_cycle_work_j(world, trajectory, a, b):
    """Friction and viscous work over [a, b] from the dense motion (Simpson, 40001 points)."""
    t = np.linspace(a, b, 40001)
    x, v = trajectory.evaluate(t)
    plant = world.mechanics
    mu = world.friction.sliding_mu(np.sign(v), np.abs(v), x)
    power = plant.normal_force_n * mu * np.abs(v) + plant.damping_n_s_per_m * v * v
    return scipy.integrate.simpson(power, x=t)


@pytest.mark.parametrize(
    'friction, damping',
    [
        (Stribeck(Coulomb(0.1), 0.04, 4e-3), 0.0),
        (SpeedRegimes(Coulomb(0.14), Coulomb(0.07), 0.06, 0.005), 0.0),
        (WearTrack(Coulomb(0.1), 0.3, 3e-3, 0.4), 0.0),
        (WearPatch(Coulomb(0.1), -2e-3, 1e-3, 1.8), 0.0),
        (Coulomb(0.1), 4.0),
    ],
    ids=['stribeck', 'regimes', 'track', 'patch', 'viscous'],
)
def test_energy_balance_over_each_half_cycle(friction, damping):
    """Between two velocity zeros the spring energy lost is the work done by friction and
    damping; for position-only laws that work is also the closed-form integral of mu(x)."""
    world = World(plant=Plant(damping_n_s_per_m=damping), friction=friction)
    plant = world.mechanics
    trajectory, _ = simulate_motion(world, [], 0.0, 10.0, PlantState(0.008))
    stops = [(e.time_s, e.position_m) for e in trajectory.reversals()]
    assert len(stops) >= 4
    previous = (0.0, 0.008)
    for t, x in stops:
        lost = 0.5 * plant.stiffness_n_per_m * (previous[1] ** 2 - x**2)
        if not isinstance(friction, WearPatch):
            work = _half_cycle_work_j(world, trajectory, previous[0], t)
            assert lost == pytest.approx(work, rel=1e-7, abs=1e-12)
        if isinstance(friction, (WearTrack, WearPatch)):
            lo, hi = sorted((x, previous[1]))
            if isinstance(friction, WearTrack):
                k = 2 * math.pi / friction.wavelength_m
                mean = (hi - lo) - friction.relative_amplitude / k * (
                    math.cos(k * hi + friction.phase_rad) - math.cos(k * lo + friction.phase_rad)
                )
            else:
                overlap = max(0.0, min(hi, friction.stop_m) - max(lo, friction.start_m))
                mean = (hi - lo) + (friction.factor - 1) * overlap
            assert lost == pytest.approx(plant.normal_force_n * 0.1 * mean, rel=2e-9)
        previous = (t, x)


# --- hammer pulses ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    'pulse',
    [
        HalfSine(1000.0, 2.2e-3),
        HalfSine(450.0, 3.4e-3, 0.05, 6300.0, 1.0),
        SkewedPulse(1450.0, 1.8e-3, rise_fraction=0.11),
        SkewedPulse(1000.0, 2.5e-3, 0.04, 4100.0, 2.0, 0.3, 1.0),
        SkewedPulse.for_impulse(1450.0, 1.64, 0.2, onset_exponent=0.8),
    ],
    ids=['half-sine', 'half-sine-ringing', 'skewed', 'skewed-ringing', 'full-skewed'],
)
def test_pulse_impulse_is_the_exact_integral(pulse):
    area, _ = scipy.integrate.quad(
        lambda t: float(pulse.force_n(t)),
        0.0,
        pulse.contact_s,
        limit=400,
        epsabs=1e-13,
        epsrel=1e-13,
    )
    assert pulse.impulse_n_s == pytest.approx(area, rel=1e-11)
    t = np.linspace(-1e-4, pulse.contact_s + 1e-4, 2001)
    assert np.allclose([pulse.force_at(ti) for ti in t], pulse.force_n(t), rtol=1e-13, atol=0)
    assert pulse.force_n(-1e-9) == 0 and pulse.force_n(pulse.contact_s + 1e-9) == 0
    if not pulse.ringing_fraction:
        assert pulse.force_n(t).max() == pytest.approx(pulse.peak_force_n, rel=1e-4)
    if isinstance(pulse, SkewedPulse) and not pulse.ringing_fraction:
        assert float(pulse.force_n(pulse.rise_s)) == pytest.approx(pulse.peak_force_n)


def test_paper_hits_have_the_paper_impulses_and_contacts():
    for (peak, impulse), contact_ms in zip(PAPER_LEVELS.values(), (3.4, 2.2, 1.8), strict=True):
        pulse = HalfSine.for_impulse(peak, impulse)
        assert pulse.impulse_n_s == pytest.approx(impulse)
        assert pulse.contact_s * 1e3 == pytest.approx(contact_ms, abs=0.05)
    sharp = SkewedPulse(1450.0, 1.8e-3, rise_fraction=0.11)
    assert sharp.rise_s == pytest.approx(0.2e-3, rel=0.02)


def test_random_pulses_scatter_about_the_paper_levels():
    rng = np.random.default_rng(3)
    by_level = {name: [random_pulse(rng, name) for _ in range(150)] for name in PAPER_LEVELS}
    for name, pulses in by_level.items():
        peak, impulse = PAPER_LEVELS[name]
        peaks = np.array([p.peak_force_n for p in pulses])
        impulses = np.array([p.impulse_n_s for p in pulses])
        assert np.all(np.abs(peaks - peak) <= 50.0) and peaks.std() > 20.0
        assert np.mean(impulses) == pytest.approx(impulse, rel=0.02)
        assert np.all(np.abs(impulses / impulse - 1) < 0.08)
        kinds = {type(p) for p in pulses}
        assert kinds == {HalfSine, SkewedPulse}
        assert 0.2 < np.mean([p.ringing_fraction > 0 for p in pulses]) < 0.5
    again = np.random.default_rng(3)
    assert random_pulse(again, 'low') == by_level['low'][0]


# --- the DAQ chain ---------------------------------------------------------------------------


@pytest.mark.parametrize('kind', ['butterworth', 'bessel', 'chebyshev1', 'elliptic'])
@pytest.mark.parametrize('order', [2, 5, 8])
def test_discretised_filter_matches_the_analog_response(kind, order):
    """First-order hold of any order: the analog response times the hold's own error
    (pi f / f_high)^2 / 3, exact at DC."""
    flt = AnalogFilter(kind, order, 4000.0)
    high = 80_000.0
    discrete = flt.discretised(high)
    f = np.linspace(0.0, 3500.0, 71)
    error = np.abs(discrete.response(f, high) / flt.response(f) - 1)
    bound = (np.pi * f / high) ** 2 / 3
    assert error[0] < 1e-12
    assert np.all(error[1:] <= 1.01 * bound[1:])
    tone = np.sin(2 * np.pi * 1000.0 * np.arange(40_000) / high)
    h = discrete.response(np.array([1000.0]), high)[0]
    steady = np.abs(h) * np.sin(2 * np.pi * 1000.0 * np.arange(40_000) / high + np.angle(h))
    assert np.abs(discrete.apply(tone) - steady)[20_000:].max() < 1e-11


def test_filtering_only_the_active_windows_is_exact():
    """The chain filters the oversampled signal only where it moves (and until the filter
    has settled); filtering the whole oversampled record must give the same samples."""
    pulses = [PlacedPulse(SkewedPulse(1450.0, 1.8e-3, rise_fraction=0.11), t) for t in (0.05, 0.3)]
    signal = ContinuousSignal(
        tuple((p.start_s, p.stop_s) for p in pulses), lambda t: sum(p.force_n(t) for p in pulses)
    )
    daq = DaqChain()
    for anti_alias in (AnalogFilter('elliptic', 8, 4000.0), AnalogFilter('bessel', 3, 1000.0)):
        chain = ChannelChain(anti_alias=anti_alias)
        windowed = analog_channel(signal, chain, daq, 5000, np.random.default_rng(0)).signal
        high = daq.sample_rate_hz * daq.oversampling
        dense = signal.deviation(np.arange(5000 * daq.oversampling) / high)
        whole = anti_alias.discretised(high).apply(dense)[:: daq.oversampling]
        assert np.abs(whole).max() > 1000.0
        assert np.abs(windowed - whole).max() < 1e-9


def _tone(frequency_hz, start_s=0.0, stop_s=1.0):
    return ContinuousSignal(
        ((start_s, stop_s),),
        lambda t: np.where(
            (t >= start_s) & (t <= stop_s), np.sin(2 * np.pi * frequency_hz * t), 0.0
        ),
    )


def test_anti_alias_filter_removes_what_would_alias():
    rng = np.random.default_rng(0)
    bare = ChannelChain(anti_alias=None)
    guarded = ChannelChain(anti_alias=AnalogFilter('elliptic', 8, 4000.0, 0.1, 80.0))
    daq = DaqChain()
    middle = slice(2000, 8000)
    n = np.arange(10_000)
    aliased = analog_channel(_tone(7000.0), bare, daq, 10_000, rng).signal
    assert np.abs(aliased[middle] + np.sin(2 * np.pi * 3000.0 * n[middle] / RATE_HZ)).max() < 1e-9
    guarded_alias = analog_channel(_tone(7000.0), guarded, daq, 10_000, rng).signal
    assert np.abs(guarded_alias[middle]).max() < 2e-4
    kept = analog_channel(_tone(1000.0), guarded, daq, 10_000, rng).signal[middle]
    _, (phasor,) = _sinusoid_fit(kept, [1000.0])
    assert abs(phasor) == pytest.approx(abs(guarded.anti_alias.response(1000.0)[0]), rel=1e-3)


@pytest.mark.parametrize(
    'anti_alias, tolerance',
    [
        (AnalogFilter(), 2e-3),
        (AnalogFilter('elliptic', 6, 3000.0), 2e-3),
        (AnalogFilter('bessel', 4, 2000.0), 2e-3),
        (None, 2e-2),
    ],
)
def test_filtered_force_keeps_the_impulse(anti_alias, tolerance):
    """A low-pass keeps a pulse's area times its DC gain, and the trapezoid of its samples
    finds it; without a filter a sharp, ringing pulse is under-sampled and the sum is off."""
    pulse = PlacedPulse(SkewedPulse(1450.0, 1.8e-3, 0.03, 3700.0, rise_fraction=0.11), 0.10003)
    signal = ContinuousSignal(((pulse.start_s, pulse.stop_s),), pulse.force_n)
    chain = ChannelChain(anti_alias=anti_alias)
    force = analog_channel(signal, chain, DaqChain(), 3000, np.random.default_rng(0)).signal
    gain = 1.0 if anti_alias is None else anti_alias.response(0.0)[0].real
    error = np.trapezoid(force) / RATE_HZ / (gain * pulse.pulse.impulse_n_s) - 1
    assert abs(error) < tolerance
    if anti_alias is None:
        assert abs(error) > 2e-3


def _sinusoid_fit(samples, frequencies_hz):
    t = np.arange(samples.size) / RATE_HZ
    columns = [np.ones_like(t)] + [
        f(2 * np.pi * fr * t) for fr in frequencies_hz for f in (np.sin, np.cos)
    ]
    coefficients = np.linalg.lstsq(np.column_stack(columns), samples, rcond=None)[0]
    # A sin(w t + phi) = A cos(phi) sin(w t) + A sin(phi) cos(w t): phasor A e^(i phi).
    return coefficients[0], coefficients[1::2] + 1j * coefficients[2::2]


@pytest.mark.parametrize('mains_hz', [50.0, 60.0])
def test_hum_is_what_the_truth_reports(mains_hz):
    anti_alias = AnalogFilter('butterworth', 2, 300.0)
    chain = ChannelChain(anti_alias=anti_alias, hum_amplitude=0.3, offset=0.2)
    daq = DaqChain(mains_hz=mains_hz)
    silent = ContinuousSignal((), lambda t: np.zeros_like(t))
    channel = analog_channel(silent, chain, daq, 20_000, np.random.default_rng(1))
    frequencies = [c.frequency_hz for c in channel.hum]
    assert frequencies == [mains_hz * h for h in daq.hum_harmonics]
    assert channel.hum[0].amplitude == 0.3
    assert all(c.amplitude < 0.3 * 0.5 / h for c, h in zip(channel.hum[1:], (2, 3, 5), strict=True))
    offset, phasors = _sinusoid_fit(channel.interference, frequencies)
    expected = [
        c.amplitude * np.exp(1j * c.phase_rad) * anti_alias.response(c.frequency_hz)[0]
        for c in channel.hum
    ]
    assert np.abs(phasors - expected).max() < 1e-9 * 0.3
    assert offset == pytest.approx(0.2, rel=1e-9)
    other = analog_channel(silent, chain, daq, 20_000, np.random.default_rng(2))
    assert other.hum != channel.hum


def test_noise_steps_and_full_scale_of_the_adc():
    chain = ChannelChain(anti_alias=None, noise_std=0.2, full_scale=5000.0, adc_bits=16)
    silent = ContinuousSignal((), lambda t: np.zeros_like(t))
    channel = analog_channel(silent, chain, DaqChain(), 200_000, np.random.default_rng(4))
    assert channel.interference.std() == pytest.approx(0.2, rel=0.01)
    samples = digitise(channel.total, chain)
    counts = samples / chain.adc_step
    assert np.array_equal(counts, np.round(counts)) and chain.adc_step == pytest.approx(
        0.1526, rel=1e-3
    )
    assert np.abs(samples - channel.total).max() <= 0.5 * chain.adc_step * (1 + 1e-12)
    assert np.array_equal(
        digitise(np.array([9e3, -9e3, 4999.99]), chain),
        [5000.0 - chain.adc_step, -5000.0, 5000.0 - chain.adc_step],
    )


def test_drift_is_a_random_walk_and_pink_noise_is_one_over_f():
    silent = ContinuousSignal((), lambda t: np.zeros_like(t))
    drift = ChannelChain(anti_alias=None, drift_per_sqrt_s=1e-5)
    walks = np.array(
        [
            analog_channel(
                silent, drift, DaqChain(), 40_000, np.random.default_rng(seed)
            ).interference
            for seed in range(200)
        ]
    )
    assert np.all(walks[:, 0] == 0)
    for seconds in (1, 4):
        assert walks[:, seconds * 10_000 - 1].std() == pytest.approx(
            1e-5 * math.sqrt(seconds), rel=0.15
        )
    pink = ChannelChain(anti_alias=None, pink_noise_std=1e-3)
    noise = analog_channel(silent, pink, DaqChain(), 2**18, np.random.default_rng(9))
    assert noise.interference.std() == pytest.approx(1e-3)
    f, power = scipy.signal.welch(noise.interference, RATE_HZ, nperseg=2**14)
    band = (f > 5) & (f < 2000)
    slope = np.polyfit(np.log(f[band]), np.log(power[band]), 1)[0]
    assert slope == pytest.approx(-1.0, abs=0.1)


# --- what the vibrometer sees ----------------------------------------------------------------


def test_vibrometer_lag_is_a_pure_delay_and_offsets_show_before_the_hit():
    world = World(effects=(VibrometerLag(1.3e-3), VelocityOffset(2e-4)))
    daq = replace(QUIET, force=replace(QUIET.force, offset=0.4))
    record = impact_record(
        world, np.random.default_rng(2), pulse=MEDIUM, daq=daq, start_position_m=1e-4
    )
    t = record.time_s
    moving = (t > 0.2) & (t < 2.0)
    lagged = record.truth.true_velocity_m_s(t[moving] - 1.3e-3)
    assert np.abs(record.velocity_m_s[moving] - 2e-4 - lagged).max() < 1e-9
    assert (
        np.abs(record.velocity_m_s[moving] - 2e-4 - record.truth.true_velocity_m_s(t[moving])).max()
        > 1e-4
    )
    before = t < record.truth.hits[0].time_s
    assert record.velocity_m_s[before] == pytest.approx(2e-4, abs=1e-9)
    assert record.force_n[before] == pytest.approx(0.4, abs=QUIET.force.adc_step)


@pytest.mark.slow
def test_second_mode_is_the_linear_response_to_the_pulse():
    """Checked against Duhamel's integral of the mode's impulse response over the pulse."""
    mode = SecondMode(frequency_hz=45.0, damping_ratio=0.002, modal_mass_kg=80.0)
    world = World(effects=(mode,))
    pulse = SkewedPulse.for_impulse(1000.0, 1.42, 0.3)
    record = impact_record(world, np.random.default_rng(0), pulse=pulse, daq=QUIET)
    hit = record.truth.hits[0]
    # Every 7th sample to the record's end: the mode rings on after the rig has stopped.
    after = np.flatnonzero(record.time_s > hit.time_s + 0.01)[::7]
    t = record.time_s[after]
    mode_velocity = record.velocity_m_s[after] - record.truth.true_velocity_m_s(t)
    mass, damping, stiffness = mode.constants
    decay, omega = damping / (2 * mass), math.sqrt(stiffness / mass)
    damped = math.sqrt(omega**2 - decay**2)
    nodes, weights = scipy.special.roots_legendre(200)
    s = hit.time_s + 0.5 * (nodes + 1) * pulse.contact_s
    tau = t[:, None] - s[None, :]
    response = (
        np.exp(-decay * tau) * (np.cos(damped * tau) - decay / damped * np.sin(damped * tau)) / mass
    )
    duhamel = response @ (0.5 * pulse.contact_s * weights * pulse.force_n(s - hit.time_s))
    assert np.abs(duhamel).max() > 5e-3
    assert np.abs(mode_velocity - duhamel).max() < 1e-9
    assert hit.rest_time_s < 10.0 and np.abs(duhamel[t > 10.0]).max() > 1e-5
    direct = linear_response(*mode.constants, hit.pulses, 0.0, 33.0)
    assert np.abs(direct.evaluate(t)[1] - duhamel).max() < 1e-9


# --- sessions and records ----------------------------------------------------------------------


@pytest.fixture(scope='module')
def session():
    damage = {
        1: [DoubleHit(0.7, 0.05)],
        2: [ForceClip(0.5)],
        3: [DeadVibrometer()],
        4: [VibrometerSaturation(0.04)],
        5: [NonFiniteBurst('both', 0.3, 40)],
        6: [DroppedSamples(0.8, 123)],
    }
    return record_session(
        World(),
        np.random.default_rng(21),
        hits=8,
        spacing_s=(34.0, 36.0),
        run_in=RunIn(1.3, 2.0),
        damage=damage,
    )


def test_generation_is_reproducible_from_the_seed():
    def make(seed):
        return record_session(
            World(effects=(SecondMode(),)),
            np.random.default_rng(seed),
            hits=2,
            spacing_s=(5.0, 6.0),
            tail_s=3.0,
            damage={1: [random_damage(np.random.default_rng(seed))]},
        )

    first, again, other = make(7), make(7), make(8)
    for name in ('force_n', 'velocity_m_s', 'time_s'):
        assert np.array_equal(getattr(first, name), getattr(again, name), equal_nan=True)
    assert repr(first.truth.hits) == repr(again.truth.hits)  # repr: NaN != NaN
    assert not np.array_equal(first.velocity_m_s, other.velocity_m_s, equal_nan=True)


def test_each_hit_starts_where_the_previous_one_stopped(session):
    hits = session.truth.hits
    assert len(hits) == 8
    band = World().static_band_m()
    for previous, hit in zip(hits[:-1], hits[1:], strict=True):
        assert hit.start_position_m == previous.rest_position_m
        assert previous.rest_time_s < hit.time_s
    starts = np.array([hit.start_position_m for hit in hits])
    assert np.all(np.abs(starts) <= 1.3 * band) and np.abs(starts).max() > 0.1 * band
    for hit in hits:
        mu_static = hit.friction.static_mu(1, 0.0, 0.0)
        assert abs(hit.rest_position_m) <= _band_m(World(), mu_static) * (1 + 1e-12)


def test_run_in_drifts_mu_from_hit_to_hit(session):
    mus = np.array([hit.mu for hit in session.truth.hits])
    assert mus == pytest.approx(0.113 * (1 + 0.3 * np.exp(-np.arange(8) / 2.0)))
    assert session.truth.hits[0].friction == Coulomb(0.113 * 1.3)


def test_truth_locates_every_hit_in_the_samples(session):
    force = np.nan_to_num(session.force_n)
    for hit in session.truth.hits:
        crossing = int(np.argmax(force[int(hit.sample_position) - 5 :] > 50.0))
        first = int(hit.sample_position) - 5 + crossing
        assert 0 < first - hit.sample_position < 12
        assert session.time_s[first] - hit.time_s == pytest.approx(
            (first - hit.sample_position) / RATE_HZ, abs=1e-9
        )
    assert session.truth.hits[1].impulse_n_s == pytest.approx(
        1.7 * session.truth.hits[1].pulses[0].pulse.impulse_n_s
    )


def test_records_cut_from_a_session_hold_the_hit_after_the_pretrigger(session):
    records = session.records(pretrigger_s=0.05)
    assert [r.force_n.size for r in records] == [330_000] * 6 + [330_000 - 123, 330_000]
    for record, hit in zip(records, session.truth.hits, strict=True):
        (inside,) = record.truth.hits
        assert inside.index == hit.index
        assert 499 < inside.sample_position <= 500
        assert inside.time_s == pytest.approx(inside.sample_position / RATE_HZ, abs=1e-9)
        assert inside.pulses[0].start_s == inside.time_s
        assert inside.rest_time_s - inside.time_s == pytest.approx(hit.rest_time_s - hit.time_s)
        first = int(np.searchsorted(session.time_s, record.truth.start_time_s - 1e-9))
        assert np.array_equal(
            record.force_n, session.force_n[first : first + record.force_n.size], equal_nan=True
        )
        assert record.truth.true_velocity_m_s(inside.time_s + 0.1) == pytest.approx(
            session.truth.true_velocity_m_s(hit.time_s + 0.1)
        )


def test_measured_velocity_is_the_true_motion_plus_noise():
    daq = replace(
        QUIET, velocity=replace(QUIET.velocity, noise_std=1e-4, full_scale=0.5, adc_bits=16)
    )
    residuals = []
    for seed in range(4):
        record = impact_record(World(), np.random.default_rng(seed), daq=daq)
        residuals.append(record.velocity_m_s - record.truth.true_velocity_m_s(record.time_s))
    residual = np.concatenate(residuals)
    assert residual.std() == pytest.approx(1e-4, rel=0.01)
    assert abs(residual.mean()) < 1e-6


def test_isolated_records_start_where_asked_or_inside_the_band():
    world = World()
    record = impact_record(world, np.random.default_rng(0), pulse=MEDIUM, start_position_m=2.5e-4)
    (hit,) = record.truth.hits
    assert hit.start_position_m == 2.5e-4 and record.force_n.size == 330_000
    assert 499 < hit.sample_position <= 500 and hit.impulse_n_s == MEDIUM.impulse_n_s
    rng = np.random.default_rng(1)
    starts = [impact_record(world, rng, daq=QUIET).truth.hits[0].start_position_m for _ in range(6)]
    assert all(abs(x) < 0.95 * world.static_band_m() for x in starts)
    assert len(set(starts)) == 6
    released = impact_record(
        world, np.random.default_rng(0), pulse=MEDIUM, daq=QUIET, start_position_m=5e-3
    )
    assert np.abs(released.velocity_m_s[:400]).max() > 1e-3  # moving before the hit


# --- damage ------------------------------------------------------------------------------------


def _span(session, index):
    hits = session.truth.hits
    start = hits[index].time_s - 0.5
    stop = hits[index + 1].time_s - 0.5 if index + 1 < len(hits) else math.inf
    return (session.time_s >= start) & (session.time_s < stop)


def test_force_clip_flattens_only_the_damaged_hit(session):
    clipped = session.force_n[_span(session, 2)]
    level = clipped.max()
    assert np.count_nonzero(clipped == level) >= 5
    assert level == pytest.approx(0.5 * session.truth.hits[2].peak_force_n, rel=0.05)
    healthy = session.force_n[_span(session, 0)]
    assert healthy.max() == pytest.approx(session.truth.hits[0].peak_force_n, rel=0.05)
    assert np.count_nonzero(healthy == healthy.max()) < 3


def test_double_hit_puts_a_second_pulse_in_the_force(session):
    hit = session.truth.hits[1]
    first, second = hit.pulses
    assert second.start_s - first.start_s == pytest.approx(0.05)
    assert second.pulse.peak_force_n == pytest.approx(0.7 * first.pulse.peak_force_n)
    around = np.abs(session.time_s - (second.start_s + 0.5 * second.pulse.contact_s)) < 2e-3
    assert session.force_n[around].max() == pytest.approx(second.pulse.peak_force_n, rel=0.05)


def test_dead_and_saturated_vibrometer(session):
    dead = session.velocity_m_s[_span(session, 3)]
    assert dead.std() < 2e-4 and np.abs(dead).max() < 1e-3
    live = session.velocity_m_s[_span(session, 2)]
    assert np.abs(live).max() > 0.05
    saturated = session.velocity_m_s[_span(session, 4)]
    assert np.abs(saturated).max() <= 0.04
    assert np.count_nonzero(np.abs(saturated) >= 0.04 - 2e-5) > 100
    constant = impact_record(
        World(), np.random.default_rng(0), damage=[DeadVibrometer(constant_m_s=0.002)]
    )
    assert np.unique(constant.velocity_m_s).size == 1


def test_non_finite_burst_and_dropped_samples(session):
    bad = ~np.isfinite(session.force_n)
    assert np.count_nonzero(bad) == 40 and np.array_equal(bad, ~np.isfinite(session.velocity_m_s))
    assert session.time_s[bad][0] == pytest.approx(
        session.truth.hits[5].time_s + 0.3, abs=1.5 / RATE_HZ
    )
    steps = np.diff(session.time_s) * RATE_HZ
    jumps = np.flatnonzero(np.abs(steps - 1) > 1e-6)
    assert jumps.size == 1 and steps[jumps[0]] == pytest.approx(124)
    assert session.time_s[jumps[0]] == pytest.approx(
        session.truth.hits[6].time_s + 0.8, abs=1.5 / RATE_HZ
    )
    later = session.truth.hits[7]
    assert later.sample_position == pytest.approx(later.time_s * RATE_HZ - 123)


def test_random_damage_covers_every_kind():
    rng = np.random.default_rng(0)
    assert {type(random_damage(rng)) for _ in range(200)} == set(DAMAGE_KINDS)


# --- files -------------------------------------------------------------------------------------


def test_csv_is_what_the_product_reads(tmp_path, session):
    from fmm_ros.core.signal.records import read_impact_csv

    # Short records keep the files small; the format does not depend on the length.
    records = session.records(duration_s=2.0)
    record = records[0]
    path = write_record_csv(tmp_path / 'hit.csv', record)
    assert path.read_text().splitlines()[0] == 'time_s,force_n,velocity_m_s'
    read = read_impact_csv(path)
    assert read.sample_rate_hz == pytest.approx(RATE_HZ)
    assert np.array_equal(read.force_n, record.force_n)
    assert np.array_equal(read.velocity_m_s, record.velocity_m_s)
    for damaged, problem in ((records[5], 'not finite'), (records[6], 'uniform')):
        with pytest.raises(ValueError, match=problem):
            read_impact_csv(write_record_csv(tmp_path / 'bad.csv', damaged))
