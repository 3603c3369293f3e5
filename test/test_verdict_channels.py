"""One session's diagnosis says the same from `fmm diagnose --json`, /fmm/diagnose_model and
the report: the verdict, which parameters ended on a bound, and what these records cannot show.
"""

import html
import json

import numpy as np
import pytest
from rclpy.node import Node

from fmm_interfaces.srv import DiagnoseModel
from fmm_ros.cli import main
from fmm_ros.constants import DIAGNOSE_SERVICE
from fmm_ros.core.signal.analysis import analyze_impact
from fmm_ros.core.signal.records import read_impact_csv, write_impact_csv
from fmm_ros.report.session import AT_BOUND
from fmm_ros.ros import msgs
from fmm_ros.ros.nodes.fitter import Fitter, HeldImpact
from fmm_ros.sim.hidden_effects import hidden_effect_case

pytestmark = [pytest.mark.ros, pytest.mark.slow]


@pytest.fixture(scope='module')
def session_files(tmp_path_factory):
    """Three 8 s hits of a Gaussian Stribeck contact, one CSV each: with fitted starts the
    diagnosis names stribeck, its exponent ends on its bound (2), and it states that these
    records cannot show an asymmetry."""
    directory = tmp_path_factory.mktemp('stribeck')
    case = hidden_effect_case('stribeck', np.random.default_rng([45, 2]), duration_s=8.0)
    paths = []
    for index, record in enumerate(case.records):
        path = directory / f'hit{index}.csv'
        write_impact_csv(path, record.force_n, record.velocity_m_s, record.sample_rate_hz)
        paths.append(str(path))
    return directory, paths


def test_cli_service_and_report_carry_the_same_verdict(session_files, ros_graph, capsys):
    directory, paths = session_files
    assert main(['diagnose', *paths, '--json']) == 0
    cli = json.loads(capsys.readouterr().out)
    assert cli['missing_effect'] == 'stribeck'
    at_bound = {name for name, flag in cli['parameter_at_bound'].items() if flag}
    unobservable = {
        c['effect']: c['unobservable'] for c in cli['candidates'] if 'unobservable' in c
    }
    assert 'stribeck.stribeck_exponent' in at_bound  # a shape on its bound: JSON, not verdict
    assert 'stribeck_exponent' not in cli['verdict']
    assert set(unobservable) == {'asymmetric_friction'}
    assert unobservable['asymmetric_friction'] in cli['verdict']

    fitter = ros_graph.add(Fitter)
    client = ros_graph.add(Node, node_name='caller').create_client(DiagnoseModel, DIAGNOSE_SERVICE)
    ros_graph.start()
    for number, path in enumerate(paths):  # as if the analyzer had reported them
        record = read_impact_csv(path)
        flags = analyze_impact(record).flags
        fitter.impacts[number] = HeldImpact(number, '', not flags, flags, record)
    response = ros_graph.call(client, DiagnoseModel.Request(), timeout_s=300.0)
    assert response.success, response.message
    served = msgs.diagnose_response_dict(response)
    assert served['verdict'] == response.verdict == cli['verdict']
    assert served['parameter_at_bound'] == cli['parameter_at_bound']
    assert {c['effect']: c.get('unobservable') for c in served['candidates']} == {
        c['effect']: c.get('unobservable') for c in cli['candidates']
    }
    assert [e['parameter_at_bound'] for e in served['missing_effects']] == [
        e['parameter_at_bound'] for e in cli['missing_effects']
    ]

    out = directory / 'report'
    assert main(['report', *paths, '--diagnose', '-o', str(out)]) == 0
    page = (out / 'index.html').read_text(encoding='utf-8')
    assert html.escape(f'Verdict: {cli["verdict"]}', quote=False) in page
    assert html.escape(unobservable['asymmetric_friction'], quote=False) in page
    assert page.count(AT_BOUND) == len(at_bound)
