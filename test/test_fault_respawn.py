"""The respawn family's quick run (benchmarks/fault_respawn.py --quick), as CI runs it.

This is the script's one quick run in the suite (test_benchmarks.py leaves it to this file).
The fitter of the multi-process rig (as `ros2 run` starts each node) is killed with SIGKILL
once the analyzer has reported a hit, and started again at once: it must hold again every
impact it held before (its state_dir), and fit them; it must hold and count every impact
accepted live, the one in flight at the kill too (cut from the recorder's bag: without it the
run held 5 of 6); the bag must replay every impact accepted live; no node may print a
traceback; and the script must write nothing to RESULTS.md.
"""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'benchmarks'))

import fault_respawn  # noqa: E402
from results_file import RESULTS  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_a_respawned_fitter_holds_again_what_it_held(monkeypatch, capsys):
    runs = []
    measure = fault_respawn.respawn_run
    monkeypatch.setattr(
        fault_respawn, 'respawn_run', lambda *a, **k: runs.append(measure(*a, **k)) or runs[-1]
    )
    before = RESULTS.read_bytes()
    assert fault_respawn.main(['--quick']) == 0
    assert RESULTS.read_bytes() == before, 'fault_respawn.py --quick wrote RESULTS.md'
    (run,) = runs
    assert run.line() in capsys.readouterr().out
    assert run.node == 'fitter' and run.tracebacks == 0, run.line()
    assert run.accepted_live, run.line()
    assert run.restored, f'the respawned fitter restored nothing: {run.line()}'
    assert run.restored <= run.held, run.line()
    assert run.restored & run.accepted_live <= run.counted, run.line()
    assert run.accepted_live <= run.held and run.accepted_live <= run.counted, run.line()
    assert run.accepted_live <= run.replayed, run.line()
