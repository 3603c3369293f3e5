"""The fault-injection benchmark's quick run (benchmarks/fault_rig.py --quick), as CI runs it.

This is the script's one quick run in the suite (test_benchmarks.py leaves it to this file):
`main(['--quick'])` must end with status 0, print its table and write nothing to RESULTS.md,
and the rows it measured are held to what each fault should show.

A few short faults on the multi-process rig (a stalled rig_sim, a killed and respawned
analyzer, a force offset above the trigger, force in kN with velocity in in/s): every loss is
named in the ledgers, every fault that should be named is, the graph recovers, no impact id
is given to two hits, and no node prints a traceback.
"""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'benchmarks'))

import fault_rig  # noqa: E402
from results_file import RESULTS  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_quick_faults_are_named_and_recovered(monkeypatch, capsys):
    rows = []
    measure = fault_rig.quick_rows
    monkeypatch.setattr(fault_rig, 'quick_rows', lambda work: rows.extend(measure(work)) or rows)
    before = RESULTS.read_bytes()
    assert fault_rig.main(['--quick']) == 0
    assert RESULTS.read_bytes() == before, 'fault_rig.py --quick wrote RESULTS.md'
    printed = capsys.readouterr().out
    assert all(row.row() in printed for row in rows), printed
    assert [row.fault for row in rows] == [
        'rig_sim stalled 3 s',
        'analyzer SIGKILL + respawn',
        'force offset 30 N (above the trigger)',
        'force in kN, velocity in in/s',
    ]
    for row in rows:
        assert row.tracebacks == 0, row.row()
        assert row.missing_named and row.fault_named and row.recovered, row.row()
        assert row.reused_ids == 0, row.row()
    stall, restart, early, both_units = rows
    assert early.flags.get('truncated_start') == 1 and early.reported == early.hits_sent + 1
    assert both_units.reported == both_units.accepted == both_units.hits_sent == 3, both_units.row()
