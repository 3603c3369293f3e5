"""`fmm demo`: the main job runs a session through the graph and reports it."""

import json

import pytest

from fmm_ros.cli import main
from fmm_ros.core.results_schema import format_with_uncertainty
from fmm_ros.io.bags.reader import BagReader

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_demo_json_reports_the_session_and_fits_the_plant_mu(tmp_path, capsys):
    out = tmp_path / 'demo'
    code = main(['demo', '--hits-per-level', '1', '--rate-factor', '100', '--json', '-o', str(out)])
    summary = json.loads(capsys.readouterr().out)
    assert code == 0
    assert summary['hits_sent'] == summary['hits_reported'] == summary['hits_accepted'] == 3
    assert summary['mu'] == pytest.approx(summary['plant_mu'], rel=0.02)
    assert [level['name'] for level in summary['levels']] == ['low', 'medium', 'high']
    for level in summary['levels']:
        assert level['count'] == 1
        assert level['mean_impulse_n_s'] > 0.8 and level['peak_receptance_m_per_n'] > 3e-3
    assert summary['r2'] > 0.99
    assert summary['missing_effect'] == 'none', summary['diagnosis']
    assert json.loads((out / 'summary.json').read_text()) == summary
    # The live mu after each accepted hit, as the fitter published (and the recorder kept) it.
    running = summary['running_mu']
    assert [e['count'] for e in running] == [1, 2, 3]
    assert running[-1]['mu'] == pytest.approx(summary['mu'], abs=0.5 * summary['mu_stderr'])
    assert set(running[-1]['levels']) == {'low', 'medium', 'high'}
    with BagReader(summary['bag']) as reader:
        assert reader.topics['/fmm/impacts'].count == 3
        assert reader.topics['/fmm/friction'].count == 3
    page = out / 'report' / 'index.html'
    assert summary['report'] == str(page) and page.is_file()
    text = page.read_text()
    assert text.count('<img') >= 10 and (out / 'report' / 'running_mu.png').is_file()
    # The page shows the fit service's answer (not a fit of its own): its mu and errors.
    fitted = format_with_uncertainty(summary['mu'], summary['mu_stderr'])
    shown = f'μ = {fitted} fitted to 3 impacts'
    assert shown in text
    impact_ids = [entry['impact_id'] for entry in summary['impacts']]
    assert [entry['impact_id'] for entry in summary['per_file']] == impact_ids


def test_demo_refuses_to_overwrite_a_bag(tmp_path, capsys):
    (tmp_path / 'bag').mkdir()
    assert main(['demo', '-o', str(tmp_path)]) == 2
    assert 'exists: choose another --output' in capsys.readouterr().err
