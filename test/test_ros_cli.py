"""ROS from the venv: `fmm env` makes a plain shell find the package and its
node executables; `fmm ros` lists the graph, describes parameters and calls the services
where there is no `ros2`; the fit service's answer is one FrictionResult on both sides."""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from fmm_ros.cli import main
from fmm_ros.core.physics.rig import FMM_RIG

PREFIX = Path(sys.prefix)
FMM = Path(sys.executable).with_name('fmm')


@pytest.mark.slow
def test_fmm_env_makes_a_plain_shell_find_the_package_and_its_nodes(tmp_path):
    script = tmp_path / 'check.sh'
    script.write_text(
        f'eval "$({FMM} env)"\n'
        f'eval "$({FMM} env)"\n'  # twice: nothing is added twice
        'python -c "from ament_index_python.packages import get_package_prefix as p; '
        "print(p('fmm_ros'))\"\n"
        'echo "$AMENT_PREFIX_PATH"\n'
        'echo "$ROS_DISTRO"\n'
        'command -v python\n'
    )
    plain = {'HOME': str(tmp_path), 'PATH': '/usr/bin:/bin'}
    result = subprocess.run(
        ['sh', str(script)], env=plain, capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr
    prefix, ament, distro, python = result.stdout.split('\n')[:4]
    assert Path(prefix) == PREFIX and ament == str(PREFIX) and distro == 'jazzy'
    assert Path(python).parent == PREFIX / 'bin'
    for node in ('analyzer', 'fitter', 'hammer_sim', 'rig_sim', 'recorder', 'player', 'daq'):
        assert os.access(Path(prefix) / 'lib' / 'fmm_ros' / node, os.X_OK), node


@pytest.mark.slow
def test_the_venv_activate_script_sets_the_same(tmp_path):
    activate = PREFIX / 'bin' / 'activate'
    result = subprocess.run(
        ['bash', '-c', f'. {activate}; echo "$AMENT_PREFIX_PATH"; echo "$ROS_DISTRO"'],
        env={'HOME': str(tmp_path), 'PATH': '/usr/bin:/bin'},
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.stdout.split('\n')[:2] == [str(PREFIX), 'jazzy'], result.stderr


@pytest.mark.ros
@pytest.mark.slow
def test_fmm_ros_lists_the_graph_describes_parameters_and_calls_the_fit(
    ros_graph, capsys, monkeypatch
):
    from fmm_ros.ros.nodes.analyzer import Analyzer
    from fmm_ros.ros.nodes.fitter import Fitter

    ros_graph.add(Fitter)
    ros_graph.add(Analyzer)
    ros_graph.start()
    monkeypatch.setenv('ROS_DOMAIN_ID', str(ros_graph.domain_id))
    # Each call joins the graph anew; on a loaded machine discovery can take seconds.
    slow = ['--discovery-s', '4']
    assert main(['ros', 'nodes', *slow]) == 0
    nodes = capsys.readouterr().out.split()
    assert {'/fitter', '/analyzer'} <= set(nodes) and '/fmm_cli' not in nodes
    assert main(['ros', 'services', '-t', *slow]) == 0
    assert '/fmm/fit_friction [fmm_interfaces/srv/FitFriction]' in capsys.readouterr().out
    assert main(['ros', 'topics', *slow]) == 0
    assert '/fmm/impacts' in capsys.readouterr().out.split()
    assert main(['ros', 'param', 'describe', '/fitter', 'keep_last_impacts', 'mass_kg', *slow]) == 0
    described = capsys.readouterr().out
    assert 'keep_last_impacts (integer) = 60' in described
    assert 'Impact records held for fitting' in described and '1 to 10000' in described
    assert f'mass_kg (double) = {FMM_RIG.mass_kg!r}' in described
    assert 'read-only' in described
    # A real answer of the real service: nothing is held yet, so it says why.
    assert main(['ros', 'call', 'fit', '--json', *slow]) == 1
    assert 'no impact held yet' in json.loads(capsys.readouterr().out)['error']


def test_a_friction_result_crosses_the_service_unchanged():
    """What the fitter node fills is what the demo and `fmm ros call fit` read back."""
    from fmm_interfaces.srv import FitFriction
    from fmm_ros.ros import msgs
    from fmm_ros.workflows.results import FrictionResult

    sent = FrictionResult(
        0.1131,
        2.5e-6,
        FMM_RIG,
        (3, 4, 7),
        (0.1130, 0.1132, 0.1131),
        (1e-5, 2e-5, 3e-5),
        initial_positions_m=(0.0, 1.2e-4, -3e-5),
        sources=('impact 3', 'impact 4', 'impact 7'),
        impulses_n_s=(0.98, 1.42, 1.64),
        per_impact_residual_rms_m_s=(1e-5, 1.1e-5, 0.9e-5),
        per_impact_normalised_residual=(1e-4, 1e-4, 0.8e-4),
        residual_rms_m_s=1e-5,
        normalised_residual=1e-4,
        noise_std_m_s=1e-5,
        consistency_chi2=1.5,
        consistency_p_value=0.47,
    )
    received = msgs.friction_result(msgs.fill_fit_response(FitFriction.Response(), sent))
    assert received.to_dict() == sent.to_dict() and received.rig == sent.rig
    assert math.isnan(received.damping_stderr_n_s_per_m) and not received.damping_fitted
    refused = FitFriction.Response(success=False, message='no accepted impact held yet')
    with pytest.raises(ValueError, match='no accepted impact held yet'):
        msgs.friction_result(refused)


def test_fmm_ros_run_names_the_executables_it_has(capsys):
    assert main(['ros', 'run', 'talker']) == 2
    err = capsys.readouterr().err
    assert "no executable 'talker'" in err and 'analyzer' in err and 'fitter' in err


def test_no_ros2_is_needed_by_the_venv_page_commands():
    """The docs' venv page runs only what the venv has (the ros2 lines are the lab's)."""
    section = (Path(__file__).resolve().parents[1] / 'docs' / 'howto' / 'venv.md').read_text()
    commands = [
        line.split('#')[0]  # the comments name the ros2 command each stands for
        for line in section.splitlines()
        if line.startswith(('fmm ', '.venv/'))
    ]
    assert len(commands) >= 8 and not any('ros2' in command for command in commands)
    parser_commands = {c.split()[2].rstrip(':') for c in commands if c.startswith('fmm ros')}
    assert parser_commands == {'nodes', 'topics', 'services', 'call', 'param', 'run'}
