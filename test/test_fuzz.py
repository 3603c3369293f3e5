"""Untrusted files: every mutated input gives a clear error or a result, never a traceback.

Each case runs the `fmm` command a user would run on the file (fuzz_files.py: the readers,
the mutations and the guarded runner), in a forked child with an address-space limit and a
timeout. The regular test takes every mutation of every format once, deterministically; the
slow one takes 1,100 mutated files. benchmarks/bench_fuzz.py prints the statistics.
"""

import collections
from pathlib import Path

import pytest
from fuzz_files import MUTATIONS, TARGETS, fuzz

# Address-space growth a case may show: a fixed allowance for the analysis itself and a
# multiple of the file's size. The largest seen, about 25 MB, is numpy's loadtxt indexing a
# CSV line of a million empty cells in a 1.3 MB file.
GROWTH_FLOOR_BYTES = 32 << 20
GROWTH_PER_FILE_BYTE = 32


def check(cases, outcomes):
    """No traceback, hang or crash; each error names its file; memory within bounds."""
    bad = [
        (case.name, case.description, outcome.verdict, outcome.message)
        for case, outcome in zip(cases, outcomes, strict=True)
        if outcome.verdict not in ('ok', 'damage', 'error')
    ]
    assert bad == []
    unnamed = [
        (case.name, outcome.message)
        for case, outcome in zip(cases, outcomes, strict=True)
        if outcome.verdict == 'error' and Path(case.path).name not in outcome.message
    ]
    assert unnamed == []
    heavy = [
        (case.name, case.description, outcome.peak_growth_bytes)
        for case, outcome in zip(cases, outcomes, strict=True)
        if outcome.peak_growth_bytes > GROWTH_FLOOR_BYTES + GROWTH_PER_FILE_BYTE * case.size_bytes
    ]
    assert heavy == []


@pytest.mark.slow
def test_every_mutation_of_every_format_is_refused_clearly_or_read(tmp_path):
    cases, outcomes = fuzz(per_target=6, seed=2024, folder=tmp_path)
    kinds = collections.defaultdict(set)
    for case in cases:
        kinds[case.target].add(case.kind)
    assert set(kinds) == set(TARGETS)
    assert all(set(MUTATIONS) - {'text'} <= found for found in kinds.values())
    check(cases, outcomes)
    # Damage is found, not read as data: most mutations of each format are refused or named.
    verdicts = collections.Counter(outcome.verdict for outcome in outcomes)
    assert verdicts['ok'] < len(cases) / 3


@pytest.mark.slow
def test_a_thousand_mutated_files(tmp_path):
    cases, outcomes = fuzz(per_target=100, seed=7, folder=tmp_path)
    assert len(cases) >= 1000
    check(cases, outcomes)
