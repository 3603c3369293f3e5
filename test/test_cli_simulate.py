"""`fmm simulate`, run in-process through the `fmm` entry point."""

import json

import numpy as np
import pytest

from fmm_ros.cli import main
from fmm_ros.core.physics.model import simulate
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.sim.excitation import half_sine_pulse

FIG2 = [
    '--mu',
    '0.1',
    '--mass-kg',
    '1',
    '--stiffness-n-per-m',
    '5000',
    '--damping-n-s-per-m',
    '0',
    '--normal-force-n',
    '9.81',
]


def run_json(capsys, *args):
    assert main(['simulate', *args, '--json']) == 0
    return json.loads(capsys.readouterr().out)


def write_force_csv(path, time_s, force_n):
    np.savetxt(
        path,
        np.column_stack((time_s, force_n)),
        delimiter=',',
        header='time_s,force_n',
        comments='',
        fmt='%.10g',
    )


def test_json_summary_of_the_paper_free_vibration(capsys):
    summary = run_json(capsys, '--x0-m', '0.003', *FIG2, '--duration-s', '1')
    assert set(summary) == {
        'final_position_m',
        'rest_time_s',
        'natural_frequency_hz',
        'damping_ratio',
        'peak_velocity_m_s',
    }
    assert summary['final_position_m'] == pytest.approx(-0.1392e-3, abs=1e-12)
    assert summary['natural_frequency_hz'] == pytest.approx(11.254, abs=1e-3)
    assert summary['damping_ratio'] == 0.0
    assert summary['rest_time_s'] == pytest.approx(4 / 11.253953951963826, rel=1e-12)
    omega = 2 * np.pi * 11.253953951963826
    assert summary['peak_velocity_m_s'] == pytest.approx(omega * (3e-3 - 0.1962e-3), rel=1e-4)
    euler = run_json(
        capsys,
        '--x0-m',
        '0.003',
        *FIG2,
        '--duration-s',
        '1',
        '--integrator',
        'euler',
        '--sample-rate-hz',
        '112540',
    )
    assert euler['final_position_m'] == pytest.approx(-0.1392e-3, abs=1e-9)


def test_defaults_are_the_fmm_at_rest(capsys):
    summary = run_json(capsys, '--duration-s', '0.5')
    assert summary == {
        'final_position_m': 0.0,
        'rest_time_s': 0.0,
        'natural_frequency_hz': FMM_RIG.natural_frequency_hz,
        'damping_ratio': FMM_RIG.damping_ratio,
        'peak_velocity_m_s': 0.0,
    }


def test_text_summary_says_when_the_mass_is_still_sliding(capsys):
    assert main(['simulate', '--v0-m-s', '0.1', '--duration-s', '0.5']) == 0
    out = capsys.readouterr().out
    assert 'natural frequency 2.1981 Hz, damping ratio 0.0958 %' in out
    assert 'still sliding at the end' in out


def test_force_record_in_response_record_out(tmp_path, capsys):
    rate = 10_000.0
    time_s = 1.5 + np.arange(20_000) / rate  # a record need not start at zero
    force = half_sine_pulse(1000.0, 2.2e-3, rate, 2.0, start_s=0.1)
    write_force_csv(tmp_path / 'hit.csv', time_s, force)
    out = tmp_path / 'response.csv'
    summary = run_json(
        capsys, '--force-csv', str(tmp_path / 'hit.csv'), '-o', str(out), '--duration-s', '5'
    )
    with open(out, encoding='utf-8') as stream:
        assert stream.readline().strip() == 'time_s,force_n,displacement_m,velocity_m_s'
    table = np.loadtxt(out, delimiter=',', skiprows=1)
    assert table.shape == (50_000, 4)  # padded with zero force to --duration-s
    np.testing.assert_allclose(table[:, 0], 1.5 + np.arange(50_000) / rate, rtol=1e-9)
    np.testing.assert_allclose(table[:20_000, 1], force, rtol=1e-9, atol=1e-9)
    assert not table[20_000:, 1].any()
    expected = simulate(np.concatenate((force, np.zeros(30_000))), rate)
    np.testing.assert_allclose(table[:, 3], expected.velocity_m_s, rtol=1e-8, atol=1e-13)
    assert summary['rest_time_s'] == pytest.approx(1.5 + expected.rest_time_s, rel=1e-12)
    assert summary['final_position_m'] == pytest.approx(expected.rest_position_m, rel=1e-12)


def test_rig_flags_reach_the_model(tmp_path, capsys):
    args = [
        '--v0-m-s',
        '0.05',
        '--mass-kg',
        '5',
        '--stiffness-n-per-m',
        '3000',
        '--damping-n-s-per-m',
        '1',
        '--normal-force-n',
        '4',
        '--mu',
        '0.2',
        '--duration-s',
        '3',
        '--sample-rate-hz',
        '2000',
    ]
    summary = run_json(capsys, *args)
    rig = Rig(5.0, 3000.0, 1.0, 4.0)
    expected = simulate(np.zeros(6000), 2000.0, rig=rig, mu=0.2, v0_m_s=0.05)
    assert summary['final_position_m'] == expected.displacement_m[-1]
    assert summary['damping_ratio'] == pytest.approx(rig.damping_ratio)


@pytest.mark.parametrize(
    ('rows', 'extra', 'message'),
    [
        ('time_s,force_n\n0,0\n0.0001,1\n0.0003,2\n', [], 'non-uniform time step'),
        ('time_s,force_n\n0,0\n0.0001,nan\n0.0002,0\n', [], 'force_n is not finite at sample 1'),
        ('t,f\n0,0\n0.0001,1\n', [], 'expected the header time_s,force_n'),
        ('time_s,force_n\n0,0\n0.0001,x\n', [], 'hit.csv'),
        (
            'time_s,force_n\n0,0\n0.0001,1\n0.0002,0\n',
            ['--sample-rate-hz', '5000'],
            'does not match the force record',
        ),
    ],
)
def test_bad_force_records_exit_2_with_a_one_line_error(tmp_path, capsys, rows, extra, message):
    (tmp_path / 'hit.csv').write_text(rows, encoding='utf-8')
    assert main(['simulate', '--force-csv', str(tmp_path / 'hit.csv'), *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith('fmm simulate: error: ') and message in err
    assert err.count('\n') == 1


@pytest.mark.parametrize(
    ('args', 'message'),
    [
        (['--mass-kg', '0'], 'mass_kg must be positive'),
        (['--stiffness-n-per-m', '-3'], 'stiffness_n_per_m must be positive'),
        (['--mu', '-0.1'], 'mu must not be negative'),
        (['--sample-rate-hz', '20'], 'time step too coarse'),
        (['--duration-s', '0'], 'duration_s must be positive'),
        (['--x0-m', 'inf'], 'x0_m must be finite'),
        (['--force-csv', '/nonexistent/hit.csv'], 'No such file'),
    ],
)
def test_bad_arguments_exit_2_with_a_one_line_error(capsys, args, message):
    assert main(['simulate', *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith('fmm simulate: error: ') and message in err
