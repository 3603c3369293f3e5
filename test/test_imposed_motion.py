"""A record the axis model does not describe: an imposed-motion friction test (a damper).

A friction damper on a shaker, or a reciprocating tribometer, is driven by an imposed
sinusoidal displacement while the contact's force is measured. There is no inertia to
identify, the friction differs between directions, and after each reversal the force turns
over a small pre-sliding displacement. The generator below is written for this test and shares
nothing with the package: a closed-form pre-sliding element per stroke (Dahl's model, whose
force approaches the direction's Coulomb level exponentially in the displacement since the
reversal, or an elasto-plastic spring that saturates at it), per-direction Coulomb levels with
the medians of a real damper record (+12.9 / -16.9 kN), and force-sensor noise.

Fitted as an axis (F = M a + Fv v + Fc sign v + offset), such a record gives a large negative
mass (its pre-sliding acts like a spring, and against a sinusoid a spring is -M w^2): that is
reproduced first. `fmm identify-friction` must not report it: it says the record is not
described and why, and fits the model the record calls for (no inertia, Coulomb per
direction), with the friction loop and the energy per cycle, checked here against the loop area
of the generator's own force.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from fmm_ros.cli import main
from fmm_ros.core.identify.axis import identify_axis_friction

RATE_HZ = 2000.0
AMPLITUDE_M = 5e-3
FREQUENCY_HZ = 2.0
CYCLES = 10
COULOMB_POSITIVE_N = 12.9e3
COULOMB_NEGATIVE_N = 16.9e3
PRESLIDING_M = 2e-4
"""Dahl: the displacement over which the force covers 1 - 1/e of its turn after a reversal."""
NOISE_N = 100.0


def imposed_damper(
    presliding: str = 'dahl', seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Time [s], displacement [m], measured force [N] and the noiseless force [N].

    Each stroke (between reversals of the imposed x = A sin(w t)) starts from the force the
    previous one ended with. Dahl: F = s Fc_s - (s Fc_s - F0) exp(-|x - x0| / PRESLIDING_M);
    elasto-plastic: F = F0 + s k |x - x0| until it reaches s Fc_s, with k = Fc+ / PRESLIDING_M.
    """
    t = np.arange(int(CYCLES * RATE_HZ / FREQUENCY_HZ)) / RATE_HZ
    phase = 2.0 * np.pi * FREQUENCY_HZ * t
    x = AMPLITUDE_M * np.sin(phase)
    direction = np.where(np.cos(phase) >= 0.0, 1.0, -1.0)
    force = np.empty_like(x)
    current, start_x, start_force, sign = 0.0, x[0], 0.0, direction[0]
    stiffness = COULOMB_POSITIVE_N / PRESLIDING_M
    for i in range(x.size):
        if direction[i] != sign:
            sign, start_x, start_force = direction[i], x[i], current
        level = COULOMB_POSITIVE_N if sign > 0 else -COULOMB_NEGATIVE_N
        travel = abs(x[i] - start_x)
        if presliding == 'dahl':
            current = level - (level - start_force) * np.exp(-travel / PRESLIDING_M)
        else:
            spring = start_force + sign * stiffness * travel
            current = min(spring, level) if sign > 0 else max(spring, level)
        force[i] = current
    noisy = force + np.random.default_rng(seed).normal(0.0, NOISE_N, x.size)
    return t, x, noisy, force


def loop_areas(x: np.ndarray, force: np.ndarray) -> np.ndarray:
    """Area of the force-displacement loop of each whole cycle (minimum of x to the next)."""
    period = int(RATE_HZ / FREQUENCY_HZ)
    first = int(np.argmin(x[:period]))
    starts = np.arange(first, x.size, period)
    return np.array(
        [
            np.trapezoid(force[a : b + 1], x[a : b + 1])
            for a, b in zip(starts[:-1], starts[1:], strict=True)
        ]
    )


@pytest.fixture(scope='module', params=['dahl', 'elastoplastic'])
def damper(request, tmp_path_factory) -> tuple[Path, np.ndarray, np.ndarray]:
    """The record as a lab file (force in kN, as the damper's DAQ wrote it)."""
    t, x, noisy, force = imposed_damper(request.param)
    path = tmp_path_factory.mktemp('damper') / f'{request.param}.npz'
    np.savez(path, t=t, x=x, force=noisy / 1e3)
    return path, x, force


def test_the_axis_model_gives_a_negative_mass_for_an_imposed_motion() -> None:
    """The failure, reproduced: the inertial fit's mass is negative, its error large."""
    _, x, noisy, _ = imposed_damper()
    result = identify_axis_friction(noisy, x, RATE_HZ)
    assert result.mass_kg.value < -1000.0
    assert result.relative_error > 0.2
    assert not result.fits_record
    assert 'not positive' in result.why


def test_an_imposed_motion_record_gets_no_mass_and_its_friction_per_direction(
    damper, capsys
) -> None:
    path, x, force = damper
    args = ['identify-friction', str(path), '--position', 'x', '--force', 'force']
    assert main([*args, '--force-unit', 'kN', '--json']) == 0
    document = json.loads(capsys.readouterr().out)
    assert document['fits_record'] is False
    assert document['model'] == 'imposed_motion'
    # no figure of the model that does not fit is reported as a result
    for key in ('mass_kg', 'viscous_n_s_per_m', 'coulomb_n', 'offset_n', 'mass_per_direction_kg'):
        assert document[key] is None, key
    assert document['rejected']['mass_kg'] < 0.0
    assert 'hysteresis near reversals' in document['why']
    assert 'relative error' in document['why']
    imposed = document['imposed_motion']
    assert imposed['coulomb_positive_n'] == pytest.approx(COULOMB_POSITIVE_N, rel=0.01)
    assert imposed['coulomb_negative_n'] == pytest.approx(COULOMB_NEGATIVE_N, rel=0.01)
    assert imposed['coulomb_asymmetry'] >= 0.15
    assert imposed['relative_error_sliding'] < 0.02
    # what is left is at the reversals: far above the sliding part's noise
    assert imposed['residual_rms_reversals_n'] > 20.0 * imposed['residual_rms_sliding_n']
    # the energy per cycle is the loop area of the generator's noiseless force
    expected = loop_areas(x, force)
    energy = np.array(imposed['energy_per_cycle_j'])
    assert energy.size == expected.size == CYCLES - 1
    assert energy == pytest.approx(expected, rel=0.01)
    loop = imposed['friction_loop']
    assert 100 <= len(loop['displacement_m']) == len(loop['force_n']) <= 1000
    assert np.ptp(loop['displacement_m']) == pytest.approx(2.0 * AMPLITUDE_M, rel=0.01)
    assert document['units']['energy_per_cycle_j'] == 'J'


def test_the_text_report_says_the_record_is_not_fitted_and_shows_the_asymmetry(
    damper, capsys
) -> None:
    path, _, _ = damper
    args = ['identify-friction', str(path), '--position', 'x', '--force', 'force']
    assert main([*args, '--force-unit', 'kN']) == 0
    text = capsys.readouterr().out
    assert 'does not fit the record' in text
    assert 'moving - exceeds moving +' in text
    assert 'mass ' not in text.split('does not fit')[0]


def test_a_force_the_motion_does_not_explain_gets_no_model(tmp_path: Path, capsys) -> None:
    t, x, _, _ = imposed_damper()
    noise = np.random.default_rng(5).normal(0.0, 1.0, x.size)
    path = tmp_path / 'unrelated.npz'
    np.savez(path, t=t, x=x, force=noise)
    assert main(['identify-friction', str(path), '--position', 'x', '--force', 'force', '--json'])
    document = json.loads(capsys.readouterr().out)
    assert document['fits_record'] is False
    assert document['model'] is None and document['imposed_motion'] is None
    assert document['mass_kg'] is None
    assert 'does not describe it either' in document['why']
