"""Sources we did not write, into the analyzer as `ros2 run` starts it (fault_sources.py).

A plain rclpy publisher with no flow control (`benchmarks/foreign_source.py`), as its own
process, into the analyzer as its own process. A reliable KEEP_ALL writer at x50 in
500-sample batches (the pace at which the analyzer's KEEP_LAST depth-100 queues had lost 2 of
3 hits) blocks rather than drops, so nothing may be lost. A KEEP_LAST writer can overwrite
its own queue whenever the reader's acknowledgements lag by its depth, which a busy machine
causes at any pace (one 500-sample batch at x50 in a full two-worker suite run): so for it the
promise is the other half of the contract, every lost sample in the ledger and the loss named
on /diagnostics, pushed past what the analyzer takes (x100 in 100-sample batches).
"""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'benchmarks'))

import fault_sources  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_a_fast_foreign_source_that_can_be_slowed_loses_nothing(tmp_path):
    outcome = fault_sources.run_case(tmp_path / 'x50', 50.0, 500, 'keep_all')
    assert outcome.received, outcome.source_line
    assert outcome.lost == 0, outcome
    assert outcome.hits_reported == outcome.hits_sent == 3, outcome


def test_a_foreign_source_that_overwrites_is_named_and_counted_in_full(tmp_path):
    outcome = fault_sources.run_case(tmp_path / 'x100', 100.0, 100, 'keep_last')
    assert outcome.received, outcome.source_line
    assert not outcome.undercounted, outcome
    if outcome.lost:  # on an idle machine the analyzer may keep up: nothing to name then
        assert any('transport: ' in text and 'batches lost' in text for text in outcome.named)
        assert any('stream: ' in text and 'missing' in text for text in outcome.named)


def test_two_sources_on_one_topic_are_named_before_the_stream_breaks(tmp_path):
    named, log = fault_sources.two_sources_case(tmp_path / 'two')
    wanted = 'two sources publish /fmm/force: '
    assert any(wanted in text for text in named if ': sources: ' in text), named
    # By node name, or by GID while the graph does not know a node's name yet.
    said = next(text for text in named if wanted in text).split(wanted)[1]
    assert all(
        name in {'/daq_one', '/daq_two'} or name.startswith('gid ')
        for name in said.split(';')[0].split(', ')
    ), said
    lines = log.splitlines()
    at = next(k for k, line in enumerate(lines) if wanted in line)
    # Named before the stream counts any damage the second source does (within one batch).
    damage = [k for k, line in enumerate(lines) if 'refused' in line or 'never arrived' in line]
    assert not damage or at < damage[0], lines[: at + 3]


def test_damaged_samples_are_named_inside_and_between_records(tmp_path):
    outcome = fault_sources.run_case(
        tmp_path / 'damage', 10.0, 500, 'keep_last', extra=('--damage',)
    )
    assert outcome.lost == 0, outcome
    samples = [text for text in outcome.named if ': samples: ' in text]  # the last published
    assert samples, outcome.ever_named
    last = samples[0]
    # 5 NaN inside the first record, 20 between records; the infinite velocity sample; the
    # 500 samples of force holding the value before them (501 equal) between records.
    assert 'force: 25 NaN from sample 21000' in last, last
    assert '1 stuck run (501 samples) from sample 74999' in last, last
    assert 'velocity: 1 infinite from sample 71000' in last, last
    warnings = [line for line in outcome.log.splitlines() if 'damaged samples' in line]
    assert 1 <= len(warnings) <= 4, warnings  # rate-limited: once per channel, then every 10 s
