"""The hammer alone (`fmm analyze --force-only`, `core.signal.hammer`): hits, rebounds, clipping.

Force records come from a generator written here (half-sine pulses evaluated at the sample
instants, each hit at a random sub-sample time, rebounds 7-41 ms after their hit, white
noise), not from the product's simulator, at the low rates NI force recordings use.
"""

import json

import numpy as np
import pytest

from fmm_ros.cli import main
from fmm_ros.core.signal.config import CaptureConfig
from fmm_ros.core.signal.hammer import hammer_hits
from fmm_ros.core.signal.quality import quality_flags
from fmm_ros.core.signal.records import ImpactRecord

NOISE_N = 0.1


def force_record(
    rate_hz: float,
    hits: list[tuple[float, float, float]],
    seconds: float,
    *,
    rebound: tuple[float, float] | None = None,
    rail_n: float | None = None,
    seed: int = 0,
) -> np.ndarray:
    """Half-sine pulses (time s, peak N, duration s) sampled at rate_hz, with noise.

    rebound: (delay s, fraction of the peak) of a second, shorter pulse after each hit.
    rail_n: where the sensor clips.
    """
    rng = np.random.default_rng(seed)
    time_s = np.arange(int(seconds * rate_hz)) / rate_hz
    force = rng.normal(0.0, NOISE_N, time_s.size)
    pulses = list(hits)
    if rebound is not None:
        delay, fraction = rebound
        pulses += [(at + delay, fraction * peak, 0.7 * width) for at, peak, width in hits]
    for at, peak, width in pulses:
        phase = (time_s - at) / width
        inside = (phase > 0) & (phase < 1)
        force[inside] += peak * np.sin(np.pi * phase[inside])
    return force if rail_n is None else np.minimum(force, rail_n)


def spaced_hits(
    count: int, rng: np.random.Generator, width_s: float
) -> list[tuple[float, float, float]]:
    """Hits a second apart at random sub-sample times, peaks 60-300 N."""
    return [
        (0.5 + number + rng.uniform(0, 0.01), rng.uniform(60, 300), width_s)
        for number in range(count)
    ]


@pytest.mark.parametrize('rate_hz, width_s', [(1600.0, 0.0022), (1600.0, 0.003), (10_000.0, 0.002)])
def test_every_rebound_is_a_double_hit_of_its_own_hit(rate_hz, width_s):
    rng = np.random.default_rng(int(rate_hz * width_s * 1e4))
    for delay_s in (0.007, 0.015, 0.041):
        hits = spaced_hits(12, rng, width_s)
        for fraction in (0.2, 0.5):
            force = force_record(rate_hz, hits, 13.0, rebound=(delay_s, fraction))
            found = hammer_hits(force, rate_hz)
            assert len(found) == len(hits)
            assert all('double_hit' in hit.flags for hit in found), (delay_s, fraction)
        clean = hammer_hits(force_record(rate_hz, hits, 13.0), rate_hz)
        assert len(clean) == len(hits)
        assert not any('double_hit' in hit.flags for hit in clean)


def test_a_hit_is_accepted_by_the_rule_every_impact_is():
    """No rejecting flag: accepted; a flag rejects only when the analysis's reject_flags name it."""
    rate_hz = 10_000.0
    hits = spaced_hits(4, np.random.default_rng(3), 0.002)
    clean = hammer_hits(force_record(rate_hz, hits, 5.0), rate_hz)
    assert [hit.accepted for hit in clean] == [True] * 4
    rebounding = force_record(rate_hz, hits, 5.0, rebound=(0.015, 0.5))
    assert not any(hit.accepted for hit in hammer_hits(rebounding, rate_hz))
    kept = hammer_hits(rebounding, rate_hz, reject_flags=('clipped',))
    assert all('double_hit' in hit.flags and hit.accepted for hit in kept)


def test_the_impact_flags_use_the_same_rebound_rule():
    rate_hz = 1600.0
    hits = [(0.5 + 0.3 / rate_hz, 80.0, 0.0025)]
    force = force_record(rate_hz, hits, 2.0, rebound=(0.012, 0.2))
    record = ImpactRecord(force, np.zeros_like(force), rate_hz)
    assert 'double_hit' in quality_flags(record, CaptureConfig())


def test_a_one_sample_clipped_top_shared_by_several_hits_is_caught():
    rate_hz = 1600.0
    rng = np.random.default_rng(3)
    hits = spaced_hits(20, rng, 0.0025)
    force = force_record(rate_hz, hits, 21.0, rail_n=200.0)
    found = hammer_hits(force, rate_hz)
    reached = [peak > 200.0 + 5 * NOISE_N for _, peak, _ in hits]
    assert sum(reached) >= 3
    clipped = ['clipped' in hit.flags for hit in found]
    # A hit whose sampled top stayed under the rail is not flagged; every one on it is.
    on_rail = [hit.peak_force_n >= 200.0 for hit in found]
    assert clipped == on_rail
    assert sum(on_rail) >= 3
    # Without the rail, nothing is clipped; with the range stated, a hit at it is.
    assert not any(
        'clipped' in hit.flags for hit in hammer_hits(force_record(rate_hz, hits, 21.0), rate_hz)
    )
    ranged = hammer_hits(force_record(rate_hz, hits[:1], 2.0), rate_hz, force_full_scale_n=50.0)
    assert 'clipped' in ranged[0].flags


@pytest.mark.parametrize(
    'rate_hz, width_s, expect',
    [(1000.0, 0.004, True), (1600.0, 0.0028, True), (10_000.0, 0.004, False)],
)
def test_a_coarse_pulse_is_flagged_and_a_fine_one_is_not(rate_hz, width_s, expect):
    errors = []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        at = 0.5 + rng.uniform(0, 1 / rate_hz)
        force = force_record(rate_hz, [(at, 150.0, width_s)], 1.5, seed=seed)
        (hit,) = hammer_hits(force, rate_hz)
        assert ('coarse' in hit.flags) is expect
        errors.append(hit.impulse_n_s / (150.0 * width_s * 2 / np.pi) - 1)
    # What the flag is for: where the samples fall moves a coarse pulse's impulse by per cents.
    assert bool(np.ptp(errors) > 0.01) is expect
    assert np.max(np.abs(errors)) < (0.1 if expect else 0.005)


def test_force_only_cli_lists_the_hits_and_a_record_without_one(tmp_path, capsys):
    rate_hz = 1600.0
    rng = np.random.default_rng(7)
    hits = spaced_hits(5, rng, 0.003)
    time_s = np.arange(int(6 * rate_hz)) / rate_hz
    hit_file, quiet_file = tmp_path / 'hits.csv', tmp_path / 'quiet.csv'
    for path, force in (
        (hit_file, force_record(rate_hz, hits, 6.0, rebound=(0.02, 0.3))),
        (quiet_file, force_record(rate_hz, [], 6.0)),
    ):
        np.savetxt(
            path,
            np.column_stack((time_s, force)),
            delimiter=',',
            header='time_s,force_n',
            comments='',
        )
    code = main(
        ['analyze', str(hit_file), str(quiet_file), '--continuous', '--force-only', '--json']
    )
    assert code == 0
    files = json.loads(capsys.readouterr().out)['files']
    assert [len(found['hits']) for found in files] == [5, 0]
    times = [hit['time_s'] for hit in files[0]['hits']]
    np.testing.assert_allclose(times, [at for at, _, _ in hits], atol=1.5 / rate_hz)
    assert all('double_hit' in hit['flags'] for hit in files[0]['hits'])
    assert set(files[0]['hits'][0]) == {
        'trigger_sample_index',
        'time_s',
        'peak_force_n',
        'impulse_n_s',
        'contact_time_s',
        'flags',
        'accepted',
    }
    # The same verdict field as every other hit: a double hit is rejected by default.
    assert [hit['accepted'] for hit in files[0]['hits']] == [False] * 5
    assert 'no hit' in files[1]['verdict']
    code = main(['analyze', str(quiet_file), '--continuous', '--force-only'])
    out = capsys.readouterr().out
    assert code == 0 and 'quiet.csv: no hit (the force never reaches the trigger level 20 N' in out


def test_impacts_sharing_the_top_force_are_clipped_in_a_session():
    """The analysis (fmm analyze, the analyzer node) applies the shared-top rule across hits."""
    from fmm_ros.core.signal.analysis import analyze_impact, summarize

    rate_hz = 1600.0
    rng = np.random.default_rng(11)
    results = []
    for number, peak in enumerate((150.0, 215.0, 225.0, 235.0, 245.0, 90.0)):
        at = 0.5 + rng.uniform(0, 1 / rate_hz)
        force = force_record(rate_hz, [(at, peak, 0.004)], 3.0, rail_n=200.0, seed=number)
        decay = np.exp(-np.arange(force.size) / rate_hz / 0.3)
        velocity = np.cumsum(force) / rate_hz * 1e-3 * decay
        results.append(analyze_impact(ImpactRecord(force, velocity, rate_hz), impact_id=number))
    impacts = summarize(results).impacts
    on_rail = [impact.peak_force_n == 200.0 for impact in impacts]
    assert sum(on_rail) >= 3
    # Tops of a sample or two: no plateau; only the shared top tells they were clipped.
    assert ['clipped' in impact.flags for impact in impacts] == on_rail
    assert all('clipped' not in result.flags for result in results)
