"""config/fmm_rig.yaml stays in step with the nodes' parameter tables and loads into them."""

from pathlib import Path

import pytest
import yaml

from fmm_ros.ros.nodes import (
    analyzer,
    daq,
    fitter,
    foxglove_server,
    hammer_sim,
    live,
    player,
    recorder,
    rig_sim,
    station,
)
from fmm_ros.ros.params_file import node_param_tables, params_file_text

pytestmark = pytest.mark.ros

CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'fmm_rig.yaml'
NODES = {
    module.__name__.rsplit('.', 1)[1]: module
    for module in (
        hammer_sim,
        rig_sim,
        analyzer,
        fitter,
        recorder,
        player,
        daq,
        live,
        foxglove_server,
        station,
    )
}


def test_every_node_and_every_parameter_is_in_the_config_and_valid():
    config = yaml.safe_load(CONFIG.read_text())
    assert set(config) == set(NODES)
    for name, module in NODES.items():
        values = config[name]['ros__parameters']
        params = {param.name: param for param in module.PARAMS}
        assert set(values) == set(params), f'{name}: config and PARAMS differ'
        for key, value in values.items():
            param = params[key]
            assert type(value) is type(param.default), f'{name}.{key}: {value!r} has another type'
            assert param.problem(value) is None, f'{name}.{key}: {param.problem(value)}'
            if param.limits and not isinstance(value, list):
                assert param.limits[0] <= value <= param.limits[1], f'{name}.{key} out of range'


def test_the_config_is_the_text_made_from_the_parameter_tables():
    """Descriptions, units, ranges and defaults cannot drift from the code."""
    assert CONFIG.read_text() == params_file_text(node_param_tables()), (
        'config/fmm_rig.yaml is stale: '
        '.venv/bin/python -m fmm_ros.ros.params_file > config/fmm_rig.yaml'
    )


def test_the_params_file_shows_ranges_choices_and_replaced_defaults():
    text = params_file_text(node_param_tables())
    assert (
        '    batch_size: 500  # Samples per channel per published message (>= 500 keeps '
        'rclpy cheap) [-]; 1 to 1000000\n' in text
    )
    assert (
        "# Physics integrator (euler: the paper's fixed-step reference); one of exact, rk4, euler\n"
        in text
    )
    # In a rig the sources wait for the rig's consumers; the nodes alone wait for none.
    assert "wait_for_consumers: ['rig_sim', 'analyzer', 'fitter', 'recorder']  #" in text
    assert text.count("node default ['']") == 3
    assert 'settable live' in text.split('rate_factor: 1.0', 1)[1].split('\n', 1)[0]
    assert yaml.safe_load(text)['recorder']['ros__parameters']['topics'][0] == 'fmm/force'


@pytest.mark.parametrize(
    ('node', 'cls'),
    [
        ('hammer_sim', hammer_sim.HammerSim),
        ('rig_sim', rig_sim.RigSim),
        ('analyzer', analyzer.Analyzer),
        ('fitter', fitter.Fitter),
    ],
)
def test_nodes_start_from_the_params_file(ros_graph, node, cls):
    started = ros_graph.add(cls, cli_args=['--ros-args', '--params-file', str(CONFIG)])
    assert started.config == yaml.safe_load(CONFIG.read_text())[node]['ros__parameters']
