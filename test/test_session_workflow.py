"""The session pipeline: workflows compute, the report draws, and a fit made
elsewhere (the fitter service's answer, in the demo) is drawn as it is, never refitted."""

import dataclasses
import json
import math

import pytest
from fit_records import lab_levels

from fmm_ros.core.physics.rig import FMM_RIG
from fmm_ros.core.signal.analysis import AnalysisConfig, paper_levels
from fmm_ros.core.signal.capture import CaptureConfig, with_trigger
from fmm_ros.core.signal.records import ImpactRecord, stable_impact_id, write_impact_csv
from fmm_ros.workflows import session as workflow
from fmm_ros.workflows.inputs import InputOptions
from fmm_ros.workflows.results import FrictionResult

CAPTURE = CaptureConfig(rest_velocity_m_s=1e-3)


@pytest.fixture(scope='module')
def records():
    return [
        ImpactRecord(hit.force_n, hit.velocity_m_s, hit.sample_rate_hz, source=f'hit {number}')
        for number, hit in enumerate(lab_levels(21, mu=0.113, duration_s=6.0))
    ]


def options(**values):
    return workflow.SessionOptions(
        inputs=InputOptions(capture=CAPTURE),
        analysis=AnalysisConfig(levels=paper_levels(tolerance_n=120.0)),  # a hand's scatter
        **values,
    )


def test_a_fit_made_elsewhere_is_drawn_as_given_and_not_made_again(records, monkeypatch):
    a, b, c = workflow.impact_ids(records)
    given = FrictionResult(
        0.1234, 1e-5, FMM_RIG, (a, b, c), (0.1234,) * 3, (1e-5,) * 3, (0.0, 1e-4, -1e-4)
    )

    def refit(*_, **__):
        raise AssertionError('the session fitted again')

    monkeypatch.setattr(workflow, 'fit_friction', refit)
    session = workflow.process_records(records, options(), friction=given)
    assert session.friction is given
    assert session.model.mu == 0.1234 and session.model.source == 'fitted'
    assert session.model.initial_positions_m == {a: 0.0, b: 1e-4, c: -1e-4}
    assert set(session.comparison.hits) == {a, b, c}
    with pytest.raises(ValueError, match=r'names impact\(s\) \[5\] the session lacks'):
        workflow.process_records(
            records,
            options(),
            friction=FrictionResult(0.1, 1e-5, FMM_RIG, (5,), (0.1,), (1e-5,)),
        )


@pytest.mark.slow
def test_one_session_from_files_to_a_json_summary(records, tmp_path):
    """process_session: what fmm report (and fmm campaign) run per session."""
    paths = []
    for number, record in enumerate(records):
        paths.append(tmp_path / f'{number}.csv')
        write_impact_csv(paths[-1], record.force_n, record.velocity_m_s, record.sample_rate_hz)
    steps = []
    session = workflow.process_session(paths, options(), progress=steps.append)
    summary = json.loads(json.dumps(session.to_dict(), allow_nan=False))
    assert summary['inputs'] == [str(path) for path in paths]
    assert [impact['accepted'] for impact in summary['impacts']] == [True] * 3
    assert summary['fit']['mu'] == pytest.approx(0.113, rel=0.01)
    ids = [impact.impact_id for impact in session.summary.impacts]
    assert len(set(ids)) == 3  # the files laid end to end on one axis: one id each
    assert [entry['impact_id'] for entry in summary['fit']['per_file']] == ids
    assert summary['diagnosis'] is None and summary['fit_failure'] is None
    assert all(rms < 2e-4 for rms in summary['residual_rms_m_s'].values())
    assert 'analysing hit 3/3' in steps and 'fitting mu of impact 3/3 alone' in steps
    refused = workflow.process_records(records[:1], options(model=workflow.FitOptions(rig=FMM_RIG)))
    assert refused.friction is not None  # one accepted impact is enough to fit
    none = workflow.process_records(records, options(fit=False))
    assert none.friction is None and none.comparison is None and none.fit_failure == ''


def test_records_in_hand_of_one_stream_keep_their_ids_and_files_are_laid_end_to_end(records):
    """Clockless records that follow each other on one sample axis (a bag's capture) are one
    input, with the ids the analyzer gave them live (trigger ms since sample 0); records that
    each start at sample 0 (lab files) are laid end to end, one input after another."""
    rate = records[0].sample_rate_hz
    length = max(record.force_n.size for record in records)
    on_one_axis = [
        dataclasses.replace(record, record_start_sample_index=k * (length + 1000))
        for k, record in enumerate(records)
    ]
    live = [stable_impact_id(with_trigger(record, CAPTURE)) for record in on_one_axis]
    assert workflow.impact_ids(on_one_axis, CAPTURE) == live
    files = workflow.impact_ids(records, CAPTURE)
    starts_ms = [0]
    for record in records[:-1]:
        starts_ms.append(starts_ms[-1] + math.ceil(record.force_n.size / rate * 1000) + 1)
    alone = [stable_impact_id(with_trigger(record, CAPTURE)) for record in records]
    assert files == [start + own for start, own in zip(starts_ms, alone, strict=True)]
