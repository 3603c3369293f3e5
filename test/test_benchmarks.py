"""Every benchmark runs, in its quick mode, so a benchmark that crashes fails the build.

Scripts are discovered, not listed: every file in benchmarks/ that runs as a script (it has a
`__main__` block) is run with `--quick`, so a benchmark added later is covered without
touching this test. A quick run must end with status 0 and write nothing to RESULTS.md.
"""

import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fmm_ros.core.diagnose import workflow
from fmm_ros.core.diagnose.workflow import MIN_WHOLE_EXCESS, WHOLE_MISFIT_SHARE
from fmm_ros.core.identify.spec import start_options

BENCHMARKS = Path(__file__).resolve().parents[1] / 'benchmarks'
SCRIPTS = sorted(
    path
    for path in BENCHMARKS.glob('*.py')
    if "if __name__ == '__main__':" in path.read_text(encoding='utf-8')
)
# Scripts that start ROS graphs (processes of their own, on a domain they pick).
ROS_SCRIPTS = (
    'bench_graph',
    'stress_rig',
    'fault_rig',
    'bench_station',
    'fault_sources',
    'foreign_source',
    'fault_respawn',
)
# Scripts whose quick run a test file of their own makes (and checks further): not run twice.
QUICK_RUN_BY = {'fault_rig': 'test_fault_rig.py', 'fault_respawn': 'test_fault_respawn.py'}
QUICK_TIMEOUT_S = 600  # a busy shared machine runs them several times slower


def test_the_known_benchmarks_are_discovered():
    names = {path.stem for path in SCRIPTS}
    assert {'bench_replay', 'bench_physics', 'stress_rig', 'bench_signal'} <= names
    assert 'results_file' not in names and 'closed_world_diagnose' not in names
    for script, test_file in QUICK_RUN_BY.items():
        assert script in names
        assert "main(['--quick'])" in (Path(__file__).parent / test_file).read_text('utf-8')


@pytest.mark.slow
@pytest.mark.parametrize(
    'script',
    [
        pytest.param(path, id=path.stem, marks=[pytest.mark.ros] * (path.stem in ROS_SCRIPTS))
        for path in SCRIPTS
        if path.stem not in QUICK_RUN_BY
    ],
)
def test_benchmark_runs_in_quick_mode(script: Path, tmp_path: Path):
    results = BENCHMARKS / 'RESULTS.md'
    before = results.read_bytes() if results.exists() else None
    run = subprocess.run(
        [sys.executable, str(script), '--quick'],
        cwd=tmp_path,
        env={**os.environ, 'MPLBACKEND': 'Agg', 'PYTHONUNBUFFERED': '1'},
        capture_output=True,
        text=True,
        timeout=QUICK_TIMEOUT_S,
        check=False,
    )
    output = f'{run.stdout[-3000:]}\n{run.stderr[-3000:]}'
    assert run.returncode == 0, f'{script.name} --quick failed:\n{output}'
    assert run.stdout.strip(), f'{script.name} --quick printed nothing'
    after = results.read_bytes() if results.exists() else None
    assert after == before, f'{script.name} --quick wrote RESULTS.md'


@pytest.mark.slow
def test_bench_diagnose_refuses_a_world_it_does_not_know(tmp_path: Path):
    """A mistyped --worlds name once swept nothing and said nothing."""
    run = _bench_diagnose(tmp_path, '--worlds', 'events,nope')
    assert run.returncode == 2
    assert 'unknown world(s) nope; known: ours, worlds, events' in run.stderr


@pytest.mark.slow
def test_bench_diagnose_judges_the_targets_its_kinds_judge(tmp_path: Path):
    """A held-out sweep of effects alone, without clean sessions, once divided by zero clean
    sessions when it judged the false-alarm target."""
    run = subprocess.run(
        [
            sys.executable,
            str(BENCHMARKS / 'bench_diagnose.py'),
            *('--quick', '--skip-timing', '--role', 'held-out', '--worlds', 'events'),
            *('--kinds', 'velocity_offset'),
        ],
        cwd=tmp_path,
        env={**os.environ, 'PYTHONUNBUFFERED': '1'},
        capture_output=True,
        text=True,
        timeout=QUICK_TIMEOUT_S,
        check=False,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    assert 'single effects and none, worst kind' in run.stdout
    assert 'false alarms:' not in run.stdout


@pytest.mark.slow
def test_bench_diagnose_finds_the_sessions_a_lower_floor_could_change():
    """`--floors` reads the workflow's refusals for size from the selection log: a wording
    change there must not silently leave every session undiagnosed again.

    `analytic`'s cubic session 3 at the default seed (a tuning world) accounts for 0.25x the
    noise but only 85 % of its gap: refused, and no lower floor changes that. The same log
    line at 95 % could change at a floor under its size, not over it.
    """
    sys.path.insert(0, str(BENCHMARKS))
    import bench_diagnose  # noqa: PLC0415 (a script's module, imported for its helpers)

    source = next(s for s in bench_diagnose.SOURCES if s.name == 'analytic')
    kind = 'cubic_stiffness'
    key = [bench_diagnose.DEFAULT_SEED, source.rows.index(kind), 3]
    records, hidden, _, starts = source.draw(kind, np.random.default_rng(key))
    result = bench_diagnose.diagnose(records, **start_options(starts))
    assert hidden == (kind,) and result.named_effects == ()
    (refusal,) = bench_diagnose.REFUSED_FOR_SIZE.findall(' '.join(result.selection))
    size, percent = float(refusal[0]), int(refusal[1])
    assert size < MIN_WHOLE_EXCESS and percent < 100 * WHOLE_MISFIT_SHARE
    assert not bench_diagnose.could_change_below(result, size, 0.1)

    whole = replace(
        result,
        selection=(
            f'nothing more qualifies: {kind} scores -4671 but accounts for only 0.25x '
            'the noise RMS (95 % of the squared gap)',
        ),
        candidates=(),
    )
    assert bench_diagnose.could_change_below(whole, size, 0.2)
    assert not bench_diagnose.could_change_below(whole, size, 0.26)
    with bench_diagnose.whole_misfit_floor(0.2):
        assert workflow.MIN_WHOLE_EXCESS == 0.2
    assert workflow.MIN_WHOLE_EXCESS == MIN_WHOLE_EXCESS


@pytest.mark.slow
@pytest.mark.parametrize('floors', ['0.4', '0,0.1', 'x', '0.1,,0.2'])
def test_bench_diagnose_refuses_floors_it_cannot_lower_to(floors: str, tmp_path: Path):
    """A floor at or above MIN_WHOLE_EXCESS, at 0, or not a number is named, before any sweep."""
    run = _bench_diagnose(tmp_path, '--floors', floors)
    assert run.returncode == 2
    assert f'argument --floors: {floors!r}: give comma-separated floors between 0 and' in run.stderr


def test_bench_diagnose_reports_limits_on_held_out_worlds_only(tmp_path: Path):
    """The rates at a multiple of the stated limit are a held-out measurement: a tuning world
    is refused by name, before any session is drawn."""
    run = _bench_diagnose(tmp_path, '--limit-multiples', '1.5', '--worlds', 'events,steps')
    assert run.returncode == 2
    assert '--limit-multiples reports held-out worlds only, not steps' in run.stderr


@pytest.mark.slow
def test_bench_diagnose_reports_the_rate_per_kind_at_a_multiple_of_the_limit(tmp_path: Path):
    """One clean session and one effect at 1.5x its stated limit, judged against the target."""
    results = BENCHMARKS / 'RESULTS.md'
    before = results.read_bytes()
    run = _bench_diagnose(tmp_path, '--quick', '--limit-multiples', '1.5', '--worlds', 'events')
    assert run.returncode == 0, run.stderr[-3000:]
    assert 'named at 1.5x the stated size, per kind: cubic 1 of 1; worst cubic' in run.stdout
    assert 'clean sessions that named anything: 0.00 (target at most 0.05) met' in run.stdout
    assert results.read_bytes() == before


def _bench_diagnose(cwd: Path, *arguments: str) -> subprocess.CompletedProcess:
    """bench_diagnose.py run with some arguments, its output captured as text."""
    return subprocess.run(
        [sys.executable, str(BENCHMARKS / 'bench_diagnose.py'), *arguments],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=QUICK_TIMEOUT_S,
        check=False,
    )
