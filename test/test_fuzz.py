"""Untrusted files: every mutated input gives a clear error or a result, never a traceback.

Each case runs the `fmm` command a user would run on the file (fuzz_files.py: the readers,
the mutations and the guarded runner), in a forked child with an address-space limit and a
timeout. The test takes every mutation of every format at least once, deterministically (66
files); the sweep over 1,100 mutated files is benchmarks/bench_fuzz.py, which prints the
statistics and fails on any file `failures` names, as this test does.
"""

import collections

import pytest
from fuzz_files import MUTATIONS, TARGETS, failures, fuzz


def check(cases, outcomes):
    """No traceback, hang or crash; each error names its file; memory within bounds."""
    assert failures(cases, outcomes) == {name: [] for name in failures([], [])}


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
