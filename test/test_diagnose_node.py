"""/fmm/diagnose_model: the fitter node names an effect hidden in the live simulated rig."""

import pytest
from rclpy.node import Node
from rig_graph import FAST_ANALYZER, FAST_HAMMER, params, wait_for

from fmm_interfaces.srv import DiagnoseModel
from fmm_ros.constants import DIAGNOSE_SERVICE
from fmm_ros.core.diagnose.workflow import EFFECTS
from fmm_ros.ros import msgs
from fmm_ros.ros.nodes.analyzer import Analyzer
from fmm_ros.ros.nodes.fitter import Fitter
from fmm_ros.ros.nodes.hammer_sim import HammerSim
from fmm_ros.ros.nodes.rig_sim import RigSim

pytestmark = [pytest.mark.ros, pytest.mark.slow]

OFFSET_M_S = 3e-4  # three times the vibrometer noise


def test_an_offset_in_the_rig_is_named_over_the_service(ros_graph):
    ros_graph.add(HammerSim, parameter_overrides=params(**FAST_HAMMER))
    ros_graph.add(
        RigSim, parameter_overrides=params(effects=[f'velocity_offset:offset_m_s={OFFSET_M_S}'])
    )
    ros_graph.add(Analyzer, parameter_overrides=params(**FAST_ANALYZER))
    fitter = ros_graph.add(Fitter)
    client = ros_graph.add(Node, node_name='caller').create_client(DiagnoseModel, DIAGNOSE_SERVICE)
    ros_graph.start()
    assert wait_for(lambda: len(fitter.impacts) == 3)
    response = ros_graph.call(client, DiagnoseModel.Request(), timeout_s=120.0)
    assert response.success, response.message
    assert response.missing_effect == 'velocity_offset'
    names = list(response.parameter_names)
    values = dict(zip(names, msgs.field_array(response.parameter_values), strict=True))
    assert values['velocity_offset.offset_m_s'] == pytest.approx(OFFSET_M_S, rel=0.05)
    assert dict(zip(names, response.parameter_units, strict=True))['mu'] == '1'
    assert response.gap_after <= 0.5 * response.gap_before
    # the gaps' yardstick: the rig sim's white noise, measured where the rig rests
    assert response.residual_noise_std_m_s == pytest.approx(response.noise_std_m_s, rel=0.1)
    assert set(response.candidate_effects) == set(EFFECTS)  # mu_drift too, from 3 hits
    assert list(response.missing_effects) == ['velocity_offset'] and not response.unexplained
    counts = list(response.missing_effect_parameter_counts)
    assert counts == [1] and list(response.missing_effect_parameter_names) == [
        'velocity_offset.offset_m_s'
    ]
    assert len(response.friction_speed_mu) == len(response.friction_speed_m_s) > 3
    assert len(response.friction_position_mu_stderr) == len(response.friction_position_m) > 3
    # each hit's mu (and their trend) from three hits on
    assert len(response.mu_per_hit) == 3 and list(response.selection)
    counts = list(response.candidate_parameter_counts)
    assert (
        sum(counts)
        == len(response.candidate_parameter_names)
        == len(response.candidate_parameter_values)
    )
    assert len(response.candidate_detection_limits) == len(response.candidate_effects)
    # the second mode's limit over the excited band crosses the service as a curve
    curves = dict(
        zip(response.candidate_effects, response.candidate_limit_curve_counts, strict=True)
    )
    assert curves.pop('second_mode') == 8 and not any(curves.values())
    assert len(response.candidate_limit_curve_frequencies_hz) == 8
    assert len(response.candidate_limit_curve_values) == 8
    assert response.verdict == response.message and response.where


def test_a_diagnosis_without_impacts_is_refused_with_the_reason(ros_graph):
    ros_graph.add(Fitter)
    client = ros_graph.add(Node, node_name='caller').create_client(DiagnoseModel, DIAGNOSE_SERVICE)
    ros_graph.start()
    response = ros_graph.call(client, DiagnoseModel.Request())
    assert not response.success and 'no impact held yet' in response.message
    response = ros_graph.call(client, DiagnoseModel.Request(impact_ids=[2]))
    assert not response.success and 'impacts [2] are not held' in response.message


def test_the_fitter_chains_the_starts_when_asked(ros_graph):
    """chain_starts: no start is fitted, each hit's impulse scale is (the chain follows it)."""
    ros_graph.add(HammerSim, parameter_overrides=params(**FAST_HAMMER))
    ros_graph.add(RigSim)
    ros_graph.add(Analyzer, parameter_overrides=params(**FAST_ANALYZER))
    fitter = ros_graph.add(Fitter, parameter_overrides=params(chain_starts=True))
    client = ros_graph.add(Node, node_name='caller').create_client(DiagnoseModel, DIAGNOSE_SERVICE)
    ros_graph.start()
    assert wait_for(lambda: len(fitter.impacts) == 3)
    response = ros_graph.call(client, DiagnoseModel.Request(), timeout_s=120.0)
    assert response.success, response.message
    names = list(response.parameter_names)
    assert 'impulse_scale[2]' in names and response.starts == 'chained'
    assert not any(name.startswith('initial_position_m') for name in names)
