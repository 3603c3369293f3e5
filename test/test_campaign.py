"""`fmm campaign` end to end: sessions on a local Dask cluster, the cache, failures, outputs.

A generated campaign (the simulated rig: lubricants A and C alike, B lower, at two normal
forces, each session's plant mu drawn about its condition's) runs on a LocalCluster of two
worker processes: each session's mu must come within 1 % of its plant, B - A must be found
inside its interval and C - A not declared. Sessions that cannot give a mu (a missing
folder, a file that is no bag, hits all outside the force levels) are reported with their
reason and stop nothing; a bag cut short gives what it holds and its damage. The same
claims are checked on sessions from the independent lab-data generator (test/worlds), read
as folders of per-impact CSV files.
"""

import dataclasses
import json
import shutil

import numpy as np
import pytest
from worlds import Coulomb, Plant, World, record_session, write_record_csv

from fmm_ros.campaign.cache import ResultCache, session_key
from fmm_ros.campaign.results import run_campaign, to_json, write_tables
from fmm_ros.campaign.session import FAILED, SessionOutcome, SessionSpec
from fmm_ros.campaign.table import read_campaign_table
from fmm_ros.campaign.tasks import SERIAL, run_sessions
from fmm_ros.cli import main
from fmm_ros.core.physics.rig import Rig
from fmm_ros.core.signal.analysis import AnalysisConfig, paper_levels
from fmm_ros.core.signal.capture import CaptureConfig
from fmm_ros.core.signal.records import ImpactRecord, write_impact_csv
from fmm_ros.sim.campaign import simulated_campaign
from fmm_ros.sim.excitation import impact_record
from fmm_ros.sim.session import simulated_session, write_session_bag
from fmm_ros.workflows.inputs import InputOptions
from fmm_ros.workflows.session import SessionOptions, process_records

LUBRICANTS = {'A': 0.113, 'B': 0.101, 'C': 0.113}
LOADS_N = (6.6708, 9.81)
WINDOW_S = 10.0  # short sessions: hits 10 s apart, each record 10 s
SETTINGS = SessionOptions(
    inputs=InputOptions(capture=CaptureConfig(window_s=WINDOW_S)),
    analysis=AnalysisConfig(levels=paper_levels()),
)
BROKEN = {
    'missing': 'no such file or directory',
    'not_a_bag': 'cannot read',
    'off_level': 'no clean impact to fit',
}


def add_broken_sessions(folder, table_path):
    """A cut-short bag, a missing folder, a file that is no bag, and hits off every level."""
    good = folder / 'sessions' / 'A_6.6708N_1'
    cut = folder / 'sessions' / 'cut_short'
    shutil.copytree(good, cut)
    (mcap,) = cut.glob('*.mcap')
    data = mcap.read_bytes()
    mcap.write_bytes(data[: int(len(data) * 0.75)])
    (cut / 'metadata.yaml').unlink()  # as a recorder killed mid-session leaves it
    not_a_bag = folder / 'sessions' / 'not_a_bag'
    not_a_bag.mkdir()
    (not_a_bag / 'session.mcap').write_bytes(b'\x89MCAP0\r\n' + bytes(range(256)) * 8)
    off_level = folder / 'sessions' / 'off_level'
    off_level.mkdir()
    for number in range(2):
        hit = impact_record(700.0, rng=number, duration_s=WINDOW_S)
        write_impact_csv(off_level / f'hit_{number}.csv', hit.force_n, hit.velocity_m_s, 1e4)
    with open(table_path, 'a', encoding='utf-8') as table:
        table.write('sessions/cut_short,cut_short,D,6.6708,2026-12-01,kb\n')
        table.write('sessions/missing,missing,X,6.6708,2026-12-02,kb\n')
        table.write('sessions/not_a_bag,not_a_bag,X,6.6708,2026-12-03,kb\n')
        table.write('sessions/off_level,off_level,X,6.6708,2026-12-04,kb\n')


@pytest.fixture(scope='module')
def generated(tmp_path_factory):
    folder = tmp_path_factory.mktemp('campaign')
    campaign = simulated_campaign(
        folder,
        LUBRICANTS,
        LOADS_N,
        sessions_per_condition=2,
        hits=3,
        spacing_s=WINDOW_S,
        seed=7,
    )
    add_broken_sessions(folder, campaign.table)
    return campaign


@pytest.fixture(scope='module')
def on_cluster(generated):
    """The campaign run once on a LocalCluster of two worker processes, with a cache."""
    table = read_campaign_table(generated.table)
    cache = generated.table.parent / 'cache'
    finished = []
    campaign = run_campaign(
        table,
        SETTINGS,
        by=('lubricant', 'normal_force_n'),
        trend=('normal_force_n',),
        workers=2,
        cache_dir=cache,
        on_result=lambda index, outcome: finished.append(index),
    )
    return campaign, cache, finished


@pytest.mark.slow
def test_every_session_on_the_cluster_comes_within_1_percent_of_its_plant(generated, on_cluster):
    campaign, _, finished = on_cluster
    assert sorted(finished) == list(range(len(campaign.table.sessions)))
    outcomes = dict(
        zip((s.session_id for s in campaign.table.sessions), campaign.results, strict=True)
    )
    for session_id, plant_mu in generated.session_mu.items():
        outcome = outcomes[session_id]
        assert outcome.ok, (session_id, outcome.reason)
        assert abs(outcome.mu / plant_mu - 1) < 0.01, (session_id, outcome.mu, plant_mu)
        assert len(outcome.hits) == 3 and outcome.accepted_hits >= 2  # some hits miss a level
        assert outcome.normal_force_n in LOADS_N
        assert not outcome.cached and outcome.key and outcome.cpu_seconds > 0


@pytest.mark.slow
def test_failed_sessions_are_reported_with_their_reason_and_stop_nothing(on_cluster):
    campaign, _, _ = on_cluster
    failed = dict(campaign.failed)
    assert sorted(failed) == sorted(BROKEN)
    for session_id, words in BROKEN.items():
        assert words in failed[session_id], failed[session_id]
    cut = campaign.results[[s.session_id for s in campaign.table.sessions].index('cut_short')]
    assert cut.ok and cut.problems, 'a bag cut short gives what it holds, and says so'
    assert 1 <= cut.accepted_hits < 3
    assert not any(c.values['lubricant'] == 'X' for c in campaign.comparison.conditions)


@pytest.mark.slow
def test_the_condition_effects_are_recovered_inside_their_intervals(on_cluster):
    """Fixed seed: B - A and C - A against their truth. (How often 95 % intervals cover,
    and how often a null pair is declared, is checked over many campaigns in
    test_campaign_stats.)"""
    campaign, _, _ = on_cluster
    main_effects = {
        (d.level, d.reference): d
        for d in campaign.comparison.differences
        if d.column == 'lubricant' and d.averaged
    }
    b_vs_a, c_vs_a = main_effects[('B', 'A')], main_effects[('C', 'A')]
    assert b_vs_a.estimate.ci_low <= -0.012 <= b_vs_a.estimate.ci_high and b_vs_a.different
    assert c_vs_a.estimate.ci_low <= 0.0 <= c_vs_a.estimate.ci_high and not c_vs_a.different
    assert any(v.startswith('lubricant B lowers mu by 0.01') for v in campaign.comparison.verdicts)


@pytest.mark.slow
def test_a_rerun_takes_known_sessions_from_the_cache_and_computes_an_added_one(
    generated, on_cluster
):
    campaign, cache, _ = on_cluster
    folder = generated.table.parent
    write_session_bag(
        folder / 'sessions' / 'added',
        simulated_session(
            1, levels=('low', 'medium'), spacing_s=WINDOW_S, seed=99, mu=0.105, rig=Rig()
        ),
    )
    added = folder / 'with_added.csv'
    added.write_text(generated.table.read_text() + 'sessions/added,added,B,6.6708,2026-12-05,tz\n')
    table = read_campaign_table(added)
    rerun = run_sessions(
        [s.spec for s in table.sessions], SETTINGS, cache_dir=cache, scheduler=SERIAL
    )
    by_id = dict(zip((s.session_id for s in table.sessions), rerun, strict=True))
    for session, first in zip(campaign.table.sessions, campaign.results, strict=True):
        again = by_id[session.session_id]
        # Inputs that cannot be read have no key and are tried again; the rest are cached.
        assert again.cached == (session.session_id != 'missing'), session.session_id
        assert again.mu == first.mu or not first.ok
    assert not by_id['added'].cached and abs(by_id['added'].mu / 0.105 - 1) < 0.01


@pytest.mark.slow
def test_the_cache_key_follows_data_settings_and_rig_not_the_name(tmp_path):
    folder = tmp_path / 'session'
    folder.mkdir()
    hit = impact_record(1000.0, rng=1, duration_s=WINDOW_S)
    write_impact_csv(folder / 'hit.csv', hit.force_n, hit.velocity_m_s, 1e4)
    spec = SessionSpec('one', folder)
    key = session_key(spec, SETTINGS)
    assert session_key(dataclasses.replace(spec, session_id='renamed'), SETTINGS) == key
    damped = dataclasses.replace(SETTINGS.model, fit_damping=True)
    assert session_key(spec, dataclasses.replace(SETTINGS, model=damped)) != key
    assert session_key(dataclasses.replace(spec, rig=Rig(normal_force_n=9.81)), SETTINGS) != key
    (folder / 'hit.csv').write_text((folder / 'hit.csv').read_text().replace('0.', '1.', 1))
    assert session_key(spec, SETTINGS) != key
    cache = ResultCache(tmp_path / 'cache')
    outcome = SessionOutcome('ok', mu=0.11, mu_stderr=1e-5, seconds={'fit': 1.0})
    cache.put(key, outcome)
    stored = cache.get(key)
    assert stored.cached and not outcome.cached
    # NaN fields too: the JSON texts are equal (NaN != NaN as floats).
    assert json.dumps(dataclasses.replace(stored, cached=False).to_dict()) == json.dumps(
        outcome.to_dict()
    )
    assert [p.name for p in (tmp_path / 'cache').iterdir()] == [f'{key}.json']
    cache.path(key).write_text('{"status": "ok", "hits": [{"broken": ')
    assert cache.get(key) is None  # an unreadable entry is recomputed, never trusted


def test_a_task_that_raises_fails_its_session_alone(tmp_path, monkeypatch):
    import fmm_ros.campaign.tasks as tasks

    def broken(spec, settings):
        if spec.session_id == 'bad':
            raise RuntimeError('a bug')
        return SessionOutcome('ok', mu=0.1, mu_stderr=1e-5)

    monkeypatch.setattr(tasks, 'compute_session', broken)
    specs = [SessionSpec('good', tmp_path), SessionSpec('bad', tmp_path)]
    good, bad = run_sessions(specs, SETTINGS, scheduler=SERIAL)
    assert good.ok and bad.status == FAILED
    assert bad.reason == 'the analysis raised RuntimeError: a bug'


def test_a_bug_is_an_internal_error_with_its_traceback_and_refused_data_is_not(
    tmp_path, monkeypatch, caplog
):
    import fmm_ros.campaign.tasks as tasks
    from fmm_ros.errors import BadInputError

    def compute(spec, settings):
        if spec.session_id == 'bug':
            raise KeyError('a bug')
        raise BadInputError('no force column')

    monkeypatch.setattr(tasks, 'compute_session', compute)
    specs = [SessionSpec('bug', tmp_path), SessionSpec('refused', tmp_path)]
    with caplog.at_level('ERROR', logger=tasks.__name__):
        bug, refused = run_sessions(specs, SETTINGS, scheduler=SERIAL)
    assert bug.status == refused.status == FAILED
    assert bug.internal_error and not refused.internal_error
    assert 'no force column' in refused.reason
    assert [record.exc_info[0] for record in caplog.records] == [KeyError]


@pytest.mark.slow
def test_the_tables_and_json_hold_every_session_hit_and_estimate(tmp_path, on_cluster):
    import pyarrow.csv as pa_csv
    import pyarrow.parquet as pq

    campaign, _, _ = on_cluster
    written = write_tables(campaign, tmp_path)
    assert sorted(p.name for p in written) == sorted(
        f'{name}.{ext}'
        for name in ('sessions', 'hits', 'levels', 'estimates')
        for ext in ('csv', 'parquet')
    )
    sessions = pq.read_table(tmp_path / 'sessions.parquet')
    assert sessions.num_rows == len(campaign.table.sessions)
    assert sessions.schema.field('normal_force_n').type == 'double'
    assert str(sessions.schema.field('date').type).startswith('timestamp')
    rows = sessions.to_pylist()
    assert {row['status'] for row in rows} == {'ok', 'failed'}
    assert all(row['mu'] is None for row in rows if row['status'] == 'failed')
    hits = pq.read_table(tmp_path / 'hits.parquet')
    assert hits.num_rows == sum(len(outcome.hits) for outcome in campaign.results)
    assert pa_csv.read_csv(tmp_path / 'hits.csv').num_rows == hits.num_rows
    estimates = pq.read_table(tmp_path / 'estimates.parquet').to_pylist()
    assert {row['kind'] for row in estimates} == {'condition', 'difference', 'slope'}
    document = json.loads(json.dumps(to_json(campaign), allow_nan=False))
    assert document['sessions_total'] == len(campaign.table.sessions)
    assert {f['session_id'] for f in document['failed']} == set(BROKEN)
    assert document['model']['dof'] >= 1 and document['verdicts']


@pytest.mark.slow
def test_fmm_campaign_writes_the_report_tables_and_json_and_exits_1_on_failed_sessions(
    generated, tmp_path, capsys
):
    out = tmp_path / 'out'
    code = main(
        [
            'campaign',
            str(generated.table),
            '-o',
            str(out),
            '--serial',
            '--no-cache',
            '--by',
            'lubricant,normal_force_n',
            '--trend',
            'normal_force_n,date',
            '--paper-levels',
            '--window-s',
            str(WINDOW_S),
            '--dpi',
            '60',
            '--json',
        ]
    )
    captured = capsys.readouterr()
    assert code == 1  # some sessions gave no mu
    document = json.loads(captured.out)
    assert document['by'] == ['lubricant', 'normal_force_n']
    assert document['sessions_fitted'] == len(generated.session_mu) + 1  # + the cut-short bag
    for session_id in BROKEN:
        assert f'session {session_id}:' in captured.err
    assert json.loads((out / 'campaign.json').read_text())['verdicts'] == document['verdicts']
    page = (out / 'index.html').read_text()
    for heading in (
        'Campaign and verdict',
        'mu by condition',
        'Differences between conditions',
        'Trends',
        'Sessions',
        'FRF levels',
        'How the comparison is made',
    ):
        assert f'>{heading}</h2>' in page, heading
    assert {p.name for p in out.glob('*.png')} >= {
        'conditions.png',
        'differences.png',
        'trend_1.png',
        'trend_2.png',
        'hits.png',
        'levels.png',
    }


def test_a_misspelt_column_fails_before_any_session_runs(generated, tmp_path):
    assert main(['campaign', str(generated.table), '-o', str(tmp_path), '--by', 'lubricnat']) == 2
    assert not any(tmp_path.iterdir())


# -- sessions from the independent generator --------------------------------------------------

WORLD_LUBRICANTS = {'A': 0.113, 'B': 0.101}
WORLD_RECORD_S = 12.0


@pytest.mark.slow
def test_lab_sessions_from_the_independent_generator_as_csv_folders(tmp_path):
    """Sessions of the worlds generator (continuous physics, a DAQ chain with filters, hum,
    drift and an ADC; hits finding the rig off centre), each a folder of per-impact CSV
    files: every session within 1 % of its truth, and B - A found in its interval."""
    rng = np.random.default_rng(2026)
    rows, truth = ['session,lubricant,normal_force_n'], {}
    for lubricant, mu in WORLD_LUBRICANTS.items():
        for load in LOADS_N:
            for number in range(2):
                session_mu = float(mu + rng.normal(0.0, 0.002))
                world = World(Plant(normal_force_n=load), Coulomb(session_mu))
                recorded = record_session(
                    world, rng, hits=3, spacing_s=(14.0, 16.0), tail_s=WORLD_RECORD_S
                )
                folder = tmp_path / f'{lubricant}{load:g}_{number}'
                folder.mkdir()
                for index, record in enumerate(recorded.records(duration_s=WORLD_RECORD_S)):
                    write_record_csv(folder / f'hit_{index}.csv', record)
                truth[folder.name] = [hit.mu for hit in recorded.truth.hits]
                rows.append(f'{folder.name},{lubricant},{load:.10g}')
    (tmp_path / 'lab.csv').write_text('\n'.join(rows) + '\n')
    table = read_campaign_table(tmp_path / 'lab.csv')
    campaign = run_campaign(table, SETTINGS, by=('lubricant', 'normal_force_n'), workers=2)
    for session, outcome in zip(table.sessions, campaign.results, strict=True):
        plant = truth[session.session_id]
        assert outcome.ok and outcome.accepted_hits >= 2, outcome.reason
        assert max(abs(outcome.mu / mu - 1) for mu in plant) < 0.01, (outcome.mu, plant)
    (b_vs_a,) = [
        d for d in campaign.comparison.differences if d.averaged and d.column == 'lubricant'
    ]
    assert b_vs_a.estimate.ci_low <= -0.012 <= b_vs_a.estimate.ci_high and b_vs_a.different


@pytest.mark.slow
def test_a_session_of_lab_files_is_read_through_its_mapping(tmp_path):
    """Lab files (here NPZ in kN and mm/s), each a recording of hits (continuous), read with
    the session's `fmm import` mapping file, cut as the analyzer cuts a stream, fitted."""
    session = simulated_session(1, levels=('medium', 'high'), spacing_s=WINDOW_S + 2, seed=3)
    half = int((WINDOW_S + 1) * 1e4)  # between the first record's end and the second hit
    folder = tmp_path / 'lab'
    folder.mkdir()
    for number, part in enumerate((slice(0, half), slice(half, None))):
        np.savez(
            folder / f'part_{number}.npz',
            F=session.force_n[part] / 1e3,
            V=session.velocity_m_s[part] * 1e3,
        )
    mapping = folder / 'mapping.yaml'  # in the folder, so also the check that it is no input
    mapping.write_text(
        'force: {name: F, unit: kN}\nvelocity: {name: V, unit: mm/s}\nsample_rate_hz: 10000\n'
    )
    table = tmp_path / 'lab.yaml'
    table.write_text('mapping: lab/mapping.yaml\nsessions:\n  - {session: lab, id: L1}\n')
    (spec,) = [s.spec for s in read_campaign_table(table).sessions]
    assert spec.mapping == mapping
    continuous = dataclasses.replace(SETTINGS.inputs, continuous=True)
    (outcome,) = run_sessions(
        [spec], dataclasses.replace(SETTINGS, inputs=continuous), scheduler=SERIAL
    )
    assert outcome.ok, outcome.reason
    assert len(outcome.hits) == 2 and outcome.accepted_hits >= 1, outcome.hits
    assert not any('gap' in hit.flags for hit in outcome.hits)
    assert abs(outcome.mu / session.mu - 1) < 0.01


def test_the_campaign_skips_the_model_run_only_the_report_draws():
    """process_records(compare=False): the fit and its per-hit residuals, no model run per hit."""
    hits = [impact_record(level, rng=n, duration_s=WINDOW_S) for n, level in enumerate((450, 1450))]
    records = [
        ImpactRecord(hit.force_n, hit.velocity_m_s, 1e4, source=f'hit{n}')
        for n, hit in enumerate(hits)
    ]
    drawn = process_records(records, SETTINGS)
    skipped = process_records(records, dataclasses.replace(SETTINGS, compare=False))
    assert drawn.comparison is not None and skipped.comparison is None
    assert skipped.friction.mu == drawn.friction.mu
    assert all(r > 0 for r in skipped.friction.per_impact_residual_rms_m_s)
