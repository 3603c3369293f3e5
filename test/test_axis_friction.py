"""Friction of a positioning axis: a closed-loop generator, then a real axis.

The generator (`axis_generator`, written for these tests, exact event-located motion under a
cascaded PD controller, an encoder, force noise and cogging ripple) shares nothing with the
identification. The real axis is the EMPS benchmark (test/data/emps/README.md) with its
published IDIM-LS identification.
"""

import json
from pathlib import Path

import numpy as np
import pytest
from axis_generator import Axis, simulate_axis

from fmm_ros.cli import main
from fmm_ros.core.identify.axis import AxisSpec, encoder_step, identify_axis_friction
from fmm_ros.errors import BadInputError

EMPS = Path(__file__).parent / 'data' / 'emps' / 'DATA_EMPS.mat'
PUBLISHED = {'mass_kg': 95.1089, 'viscous_n_s_per_m': 203.5034, 'coulomb_n': 20.3935}
PUBLISHED_DIRECTIONS = {
    'coulomb_positive_n': 20.1440,
    'coulomb_negative_n': 20.6277,
    'viscous_positive_n_s_per_m': 166.7061,
    'viscous_negative_n_s_per_m': 240.4236,
}
# The targets: Coulomb within 5 %, viscous within 10 %, mass within 5 % of the published values.
TOLERANCE = {'mass_kg': 0.05, 'viscous_n_s_per_m': 0.10, 'coulomb_n': 0.05}


@pytest.mark.slow
@pytest.mark.parametrize('seed', [1, 2, 3])
def test_closed_loop_axis_is_identified_within_its_errors(seed: int) -> None:
    axis = Axis()
    run = simulate_axis(axis, seed=seed, duration_s=12.0)
    result = identify_axis_friction(run.force_n, run.position_m, 1000.0)
    truth = {
        'mass_kg': axis.mass_kg,
        'coulomb_n': axis.coulomb_positive,
        'offset_n': axis.load_n,
        'viscous_n_s_per_m': axis.viscous_positive,
    }
    for name, value in truth.items():
        estimate = getattr(result, name)
        assert estimate.value == pytest.approx(value, rel=0.02), name
    for name in ('mass_kg', 'coulomb_n', 'offset_n'):
        estimate = getattr(result, name)
        assert abs(estimate.value - truth[name]) < 4.0 * estimate.stderr, name
        assert estimate.stderr >= estimate.stderr_classic * 0.5
    assert result.encoder_step_m == pytest.approx(1e-6, rel=1e-6)
    assert 0.0 < result.velocity_noise_m_s < 1e-3
    assert result.friction_map is not None
    forward = result.friction_map.speed_m_s > 0.02
    # the friction map follows Fc + Fv v on the forward side
    expected = axis.coulomb_positive + axis.viscous_positive * result.friction_map.speed_m_s
    assert np.allclose(
        result.friction_map.friction_n[forward], expected[forward], rtol=0.1, atol=1.0
    )


@pytest.mark.slow
def test_direction_dependent_friction_is_told_apart() -> None:
    axis = Axis(
        viscous_positive=45.0, viscous_negative=70.0, coulomb_positive=7.0, coulomb_negative=11.0
    )
    run = simulate_axis(axis, seed=7, duration_s=12.0)
    result = identify_axis_friction(run.force_n, run.position_m, 1000.0)
    directions = result.directions
    # the offset (load) is not separable from Fc+ - Fc-: it shifts both by the load
    assert directions['coulomb_positive'].value == pytest.approx(7.0 + axis.load_n, rel=0.04)
    assert directions['coulomb_negative'].value == pytest.approx(11.0 - axis.load_n, rel=0.04)
    assert directions['viscous_positive'].value == pytest.approx(45.0, rel=0.04)
    assert directions['viscous_negative'].value == pytest.approx(70.0, rel=0.04)
    assert directions['mass_kg'].value == pytest.approx(axis.mass_kg, rel=0.02)


@pytest.mark.slow
@pytest.mark.parametrize('kind', ['velocity', 'acceleration'])
def test_velocity_or_acceleration_records_give_the_same_axis(kind: str) -> None:
    axis = Axis()
    run = simulate_axis(axis, seed=4, duration_s=12.0)
    rng = np.random.default_rng(0)
    if kind == 'velocity':
        motion = run.velocity_m_s + rng.normal(0.0, 1e-4, run.velocity_m_s.size)
    else:
        # an accelerometer with an offset: its integral drifts and must be detrended
        motion = run.acceleration_m_s2 + 0.02 + rng.normal(0.0, 0.01, run.velocity_m_s.size)
    result = identify_axis_friction(run.force_n, motion, 1000.0, motion_kind=kind)
    assert result.mass_kg.value == pytest.approx(axis.mass_kg, rel=0.03)
    assert result.coulomb_n.value == pytest.approx(axis.coulomb_positive, rel=0.05)
    assert result.viscous_n_s_per_m.value == pytest.approx(axis.viscous_positive, rel=0.05)
    # a velocity known up to a constant cannot tell Fv v0 from an offset: none is claimed
    assert np.isnan(result.offset_n.value) == (kind == 'acceleration')


def test_emps_real_axis_matches_its_published_identification(capsys) -> None:
    status = main(
        [
            'identify-friction',
            str(EMPS),
            '--position',
            'qm',
            '--force',
            'vir',
            '--force-scale',
            'gtau',
            '--stiffness-n-per-m',
            '0',
            '--json',
        ]
    )
    assert status == 0
    document = json.loads(capsys.readouterr().out)
    for name, published in PUBLISHED.items():
        assert document[name] == pytest.approx(published, rel=TOLERANCE[name]), name
        assert document[f'{name}_stderr'] > 0.0
    for name, published in PUBLISHED_DIRECTIONS.items():
        assert document[name] == pytest.approx(published, rel=0.05), name
    assert document['offset_n'] == pytest.approx(-3.1648, abs=0.3)
    speed = document['friction_map']['speed']
    assert len(speed['speed_m_s']) == len(speed['friction_n']) >= 10
    assert min(speed['speed_m_s']) < 0.0 < max(speed['speed_m_s'])
    # 50,000 counts a revolution on the load side: a step of 50 nm
    assert document['encoder_step_m'] == pytest.approx(5e-8, rel=1e-6)
    assert document['sample_rate_hz'] == pytest.approx(1000.0, rel=1e-4)


def test_emps_with_a_numeric_drive_gain_and_text_output(capsys) -> None:
    args = ['identify-friction', str(EMPS), '--position', 'qm', '--force', 'vir']
    assert main([*args, '--force-scale', '35.15065188']) == 0
    text = capsys.readouterr().out
    assert 'Coulomb friction' in text and 'mass' in text


@pytest.mark.parametrize(
    ('extra', 'message'),
    [
        (['--position', 'nothing'], "no channel 'nothing'"),
        (['--position', 'qm', '--time', 'qg'], 'goes backwards'),
        (['--position', 'qm', '--force-unit', 'furlong'], "unit 'furlong'"),
        (['--position', 'qm', '--sample-rate-hz', '-5'], 'sample rate must be positive'),
    ],
)
def test_bad_input_is_named(extra: list[str], message: str, capsys) -> None:
    status = main(['identify-friction', str(EMPS), '--force', 'vir', *extra])
    assert status == 2
    assert message in capsys.readouterr().err


def test_a_record_without_a_time_base_is_refused(tmp_path: Path) -> None:
    from fmm_ros.workflows.axis import read_axis_record

    path = tmp_path / 'axis.npz'
    np.savez(path, force=np.zeros(100), position=np.zeros(100))
    with pytest.raises(BadInputError, match='no time base'):
        read_axis_record(path, force='force', motion='position')


def test_an_axis_moving_one_way_cannot_tell_friction_from_offset() -> None:
    t = np.arange(4000) / 1000.0
    with pytest.raises(BadInputError, match='move both ways'):
        identify_axis_friction(10.0 + 0.0 * t, 0.05 * t, 1000.0)
    with pytest.raises(BadInputError, match='too few'):
        identify_axis_friction(np.zeros(50), np.zeros(50), 1000.0)
    with pytest.raises(BadInputError, match='stiffness'):
        AxisSpec(stiffness_n_per_m=-1.0)


def test_encoder_step_is_found_or_declared_unknown() -> None:
    steps = np.cumsum(np.random.default_rng(1).integers(-3, 4, 500)) * 2.5e-6
    assert encoder_step(steps) == pytest.approx(2.5e-6)
    assert np.isnan(encoder_step(np.sin(np.linspace(0, 10, 500))))
