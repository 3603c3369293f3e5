"""Fault injection on the multi-process rig: each family lost, named, recovered.

The simulated rig as `launch_scripts/sim_rig.py --processes` starts it (one process per node,
the package's params file), a short session (hits 8 s apart, 6 s records), with one fault
injected from outside as a lab meets it:

- stall: a node frozen (SIGSTOP, then SIGCONT) for 1-30 s, as a swapped-out process, a
  debugger or a cold numba cache freezes it;
- restart: a node killed (SIGKILL) and started again (respawn);
- early trigger: the force channel with an offset above the trigger level (an amplifier not
  reset: the acquisition begins "mid-hit");
- units: the force published in each force unit of the table (hammer_sim.force_unit), the
  velocity in each velocity unit (rig_sim.velocity_unit), and one no table knows;
- disk full: the bag on a 12 MB tmpfs (needs root: CI runs as root);
- two sources: a second hammer_sim on the same namespace.

Per fault it prints: hits sent / reported / accepted (a reported hit counted once, by trigger
index), samples missing in the final ledgers (analyzer and recorder) and whether each loss
was named (a ledger that says 0 missing while samples are missing is the bug this guards),
whether the fault itself was named in a log line, whether the graph recovered (the last hit
of the session reported, and, where the fault stops, hits reported after it), the impact ids
given twice to different hits, and tracebacks in any log (must be 0).

    .venv/bin/python benchmarks/fault_rig.py [--quick]

--quick (CI, through test/test_fault_rig.py): a few short faults at x20. The full run stalls
rig_sim and the analyzer for 1, 5, 15 and 30 s and every other node for 15 s, restarts every
node, tries every unit of the table, and writes its table to RESULTS.md.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from results_file import write_section  # noqa: E402
from stress_rig import fresh_domain, ledgers  # noqa: E402

from fmm_ros.io.bags.definitions import SAMPLE_BATCH  # noqa: E402
from fmm_ros.io.bags.reader import BagReader  # noqa: E402
from fmm_ros.ros.launch import (  # noqa: E402
    SIMULATED_RIG,
    default_params_file,
    parse_overrides,
    start_processes,
    stop_processes,
    wait_for_log,
    with_wiring,
)
from fmm_ros.units import FORCE_UNITS, VELOCITY_UNITS  # noqa: E402

HIT_SPACING_S = 8.0
RATE = 20.0  # x real time: a session of 6 hits in 2.5 s of streaming
SESSION = (
    'hammer_sim.hit_spacing_s=8.0',
    'hammer_sim.first_hit_s=1.0',
    'hammer_sim.batch_size=1000',
    'analyzer.window_s=6.0',
)
IMPACT = re.compile(
    r'\[analyzer\]: impact (\d+) at sample (\d+): .*?, (accepted|rejected.*)$', re.M
)
SENT = re.compile(r'stopped: samples 0\.\.(\d+) published .*\((\d+) of (\d+) hits\)')
DONE = 'session complete'


@dataclass
class Outcome:
    """What one faulty run did, from the nodes' logs and the bag."""

    fault: str
    hits_sent: int = 0
    reported: int = 0
    accepted: int = 0
    flags: dict[str, int] = field(default_factory=dict)
    missing: int = 0
    missing_named: bool = True
    fault_named: bool = False
    recovered: bool = False
    reused_ids: int = 0
    tracebacks: int = 0
    note: str = ''

    def row(self) -> str:
        """One markdown table row."""
        flags = ', '.join(f'{k} {v}' for k, v in sorted(self.flags.items())) or '-'
        return (
            f'| {self.fault} | {self.hits_sent}/{self.reported}/{self.accepted} | {flags} | '
            f'{self.missing} ({"named" if self.missing_named else "NOT NAMED"}) | '
            f'{"yes" if self.fault_named else "no"} | {"yes" if self.recovered else "NO"} | '
            f'{self.reused_ids} | {self.tracebacks} | {self.note} |'
        )


HEADER = (
    '| fault | hits sent/reported/accepted | flags | samples missing | fault named | '
    'recovered | ids reused | tracebacks | note |\n|---|---|---|---|---|---|---|---|---|'
)


class Rig:
    """The simulated rig's processes (its five nodes unless told), logs in one directory."""

    def __init__(
        self,
        work: Path,
        rate: float,
        hits_per_level: int,
        extra: tuple[str, ...],
        nodes: tuple[str, ...] = SIMULATED_RIG,
        session: tuple[str, ...] = SESSION,
    ):
        fresh_domain()
        work.mkdir(parents=True)
        self.work = work
        self.bag = work / 'bag'
        options = [
            *session,
            f'hammer_sim.rate_factor={rate}',
            f'hammer_sim.hits_per_level={hits_per_level}',
            f'recorder.bag_path={self.bag}',
            *extra,
        ]
        self.overrides = with_wiring(nodes, parse_overrides(options, nodes))
        self.params = default_params_file()
        self.processes = dict(
            zip(
                nodes,
                start_processes(nodes, self.params, self.overrides, log_dir=work),
                strict=True,
            )
        )
        self.extra: list[subprocess.Popen] = []

    def log(self, node: str) -> str:
        """What a node has logged so far (all its processes)."""
        path = self.work / f'{node}.log'
        return path.read_text(errors='replace') if path.exists() else ''

    def wait_for(self, node: str, text: str, timeout_s: float) -> bool:
        """Wait until a node logged text; whether it did within timeout_s."""
        return wait_for_log(self.work, node, text, timeout_s)

    def respawn(self, node: str) -> None:
        """The node killed outright and started again, as a process manager respawns it."""
        process = self.processes[node]
        process.send_signal(signal.SIGKILL)
        process.wait()
        self.processes[node] = start_processes(
            [node], self.params, self.overrides, log_dir=self.work
        )[0]

    def stall(self, node: str, seconds: float) -> None:
        """The node frozen for seconds (SIGSTOP, SIGCONT)."""
        process = self.processes[node]
        process.send_signal(signal.SIGSTOP)
        time.sleep(seconds)
        process.send_signal(signal.SIGCONT)

    def stop(self) -> None:
        """Stop the rig in order (sources first), and any extra process."""
        order = list(self.processes)
        stop_processes([self.processes[n] for n in order], nodes=order)
        for process in self.extra:
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
                process.wait(10)


def run(
    work: Path,
    fault: str,
    inject: Callable[[Rig], None],
    *,
    named: str,
    rate: float,
    hits_per_level: int = 2,
    extra: tuple[str, ...] = (),
    recovers: bool = True,
) -> Outcome:
    """One session with a fault injected once the analyzer reported its first hit."""
    rig = Rig(work, rate, hits_per_level, extra)
    session_s = (1.0 + 3 * hits_per_level * HIT_SPACING_S) / rate
    try:
        rig.wait_for('hammer_sim', 'starting', 60.0)
        rig.wait_for('analyzer', '[analyzer]: impact ', 60.0)
        inject(rig)
        rig.wait_for('hammer_sim', DONE, 60.0 + 4 * session_s)
        # The last record (6 s of signal after the last hit) completes, however loaded.
        last = f'at sample {round((1.0 + (3 * hits_per_level - 1) * HIT_SPACING_S) * 1e4) + 1}'
        rig.wait_for('analyzer', last, 30.0)
    finally:
        rig.stop()
    result = outcome(rig, fault, named, recovers)
    print(result.row(), flush=True)  # as it goes: a long run shows its rows at once
    return result


def outcome(rig: Rig, fault: str, named: str, recovers: bool) -> Outcome:
    """Read a finished run: hits, flags, losses and whether each was named."""
    logs = {path.stem: path.read_text(errors='replace') for path in rig.work.glob('*.log')}
    result = Outcome(fault)
    sent = SENT.findall(logs.get('hammer_sim', ''))
    result.hits_sent = max((int(hits) for _, hits, _ in sent), default=0)
    by_trigger: dict[int, tuple[int, str]] = {}
    ids: dict[int, set[int]] = {}
    for impact_id, trigger, verdict in IMPACT.findall(logs.get('analyzer', '')):
        by_trigger[int(trigger)] = (int(impact_id), verdict)
        ids.setdefault(int(impact_id), set()).add(int(trigger))
    result.reported = len(by_trigger)
    result.accepted = sum(verdict == 'accepted' for _, verdict in by_trigger.values())
    for _, verdict in by_trigger.values():
        for flag in re.findall(r'[a-z_]+', verdict.removeprefix('rejected')) * (
            verdict != 'accepted'
        ):
            result.flags[flag] = result.flags.get(flag, 0) + 1
    result.reused_ids = sum(len(triggers) > 1 for triggers in ids.values())
    final = [entry for entry in ledgers(rig.work) if entry.node in ('analyzer', 'recorder')]
    result.missing = sum(entry.missing for entry in final)
    result.missing_named = _losses_named(rig)
    result.fault_named = any(named in text for text in logs.values())
    result.tracebacks = sum(text.count('Traceback') for text in logs.values())
    last_hit = (1.0 + (result.hits_sent - 1) * HIT_SPACING_S) * 1e4
    result.recovered = (
        any(trigger >= last_hit - 100 for trigger in by_trigger) if recovers else True
    )
    return result


def _losses_named(rig: Rig) -> bool:
    """Whether each recorded channel's ledger accounts for every sample up to the lead's end.

    Stored or counted missing: the issue's bag held velocity to 726,500 and force to
    6,890,000 with 0 missing on both. (A bag that was never closed carries no ledger.)
    """
    if not (rig.bag / 'metadata.yaml').exists():
        return True
    with BagReader(rig.bag, strict=False) as reader:
        ledger = reader.recorded_ledger
    ends = {
        topic: entry.received_samples + entry.missing_samples for topic, entry in ledger.items()
    }
    lead = max(ends.values(), default=0)
    return all(end >= lead - 1000 for end in ends.values())


# -- the faults ----------------------------------------------------------------------------


def stalls(work: Path, nodes, lengths, rate: float) -> list[Outcome]:
    rows = []
    for node in nodes:
        for seconds in lengths:
            rows.append(
                run(
                    work / f'stall_{node}_{seconds}',
                    f'{node} stalled {seconds:g} s',
                    lambda rig, node=node, seconds=seconds: rig.stall(node, seconds),
                    named='has said nothing' if seconds > 5 and node != 'hammer_sim' else '',
                    rate=rate,
                    # The session goes on well past the stall (hits after it to recover).
                    hits_per_level=math.ceil((seconds * rate / HIT_SPACING_S + 6) / 3),
                )
            )
    return rows


def restarts(work: Path, nodes, rate: float) -> list[Outcome]:
    return [
        run(
            work / f'restart_{node}',
            f'{node} SIGKILL + respawn',
            lambda rig, node=node: rig.respawn(node),
            named={'recorder': 'beside it', 'analyzer': 'joined an acquisition'}.get(node, ''),
            # Slower, and hits enough for after the respawn: a node starting on a loaded
            # machine takes 5-20 s (measured) before it takes its first batch.
            rate=rate / 4,
            hits_per_level=5,
        )
        for node in nodes
    ]


def early_trigger(work: Path, rate: float) -> Outcome:
    return run(
        work / 'early',
        'force offset 30 N (above the trigger)',
        lambda rig: None,
        named='truncated_start',
        rate=rate,
        extra=('hammer_sim.offset_n=30.0',),
    )


UNIT_SOURCES = {'force': 'hammer_sim', 'velocity': 'rig_sim'}
"""The node that publishes each quantity, and so takes its `<quantity>_unit` parameter."""


def unit_run(work: Path, units: dict[str, str], rate: float) -> Outcome:
    """One run with each quantity given published in its unit: a misread fails its hits."""
    named = [f'{quantity} in {unit}' for quantity, unit in units.items()]
    return run(
        work / '_'.join(name.replace(' ', '_').replace('/', '_') for name in named),
        ', '.join(named),
        lambda rig: None,
        named='',
        rate=rate,
        hits_per_level=1,
        extra=tuple(f'{UNIT_SOURCES[q]}.{q}_unit={unit}' for q, unit in units.items()),
    )


def units(work: Path, force_units, velocity_units, rate: float) -> list[Outcome]:
    """A run for each foreign unit of each quantity, one quantity at a time."""
    return [
        unit_run(work, {quantity: unit}, rate)
        for quantity, unit_list in (('force', force_units), ('velocity', velocity_units))
        for unit in unit_list
    ]


def two_sources(work: Path, rate: float) -> Outcome:
    def second(rig: Rig) -> None:
        logs = rig.work / 'second'
        logs.mkdir()
        rig.extra += start_processes(
            ['hammer_sim'], rig.params, {'hammer_sim': rig.overrides['hammer_sim']}, logs
        )
        wait_for_log(logs, 'hammer_sim', 'starting', 60.0)
        time.sleep(3.0)
        rig.extra[-1].send_signal(signal.SIGINT)
        rig.extra[-1].wait(10)

    return run(
        work / 'two_sources',
        'a second hammer_sim publishing for 3 s',
        second,
        named='two sources publish',
        rate=rate,
        recovers=False,
    )


def disk_full(work: Path, rate: float) -> Outcome:
    """The bag on a 12 MB tmpfs: the recorder stops writing, says so once, the rig goes on."""
    mount = work / 'tmpfs'
    mount.mkdir(parents=True)
    mounted = subprocess.run(
        ['mount', '-t', 'tmpfs', '-o', 'size=12m', 'tmpfs', str(mount)],
        capture_output=True,
        text=True,
    )
    if mounted.returncode:
        return Outcome('disk full (12 MB tmpfs)', note=f'not run: {mounted.stderr.strip()}')
    try:
        result = run(
            work / 'disk_full',
            'disk full (12 MB tmpfs)',
            lambda rig: None,
            named='recording to',
            rate=rate,
            hits_per_level=3,
            extra=(f'recorder.bag_path={mount / "bag"}',),
        )
        with BagReader(mount / 'bag', strict=False) as reader:
            ends = [
                batch.first_sample_index + len(batch.samples)
                for batch in reader.sample_batches([reader.find('fmm/force', SAMPLE_BATCH)])
            ]
        result.note = f'bag readable to sample {max(ends, default=0)}'
        return result
    finally:
        subprocess.run(['umount', str(mount)], check=False)


def quick_rows(work: Path, rate: float = RATE) -> list[Outcome]:
    """The CI set: a few short faults, each at high pace."""
    return [
        *stalls(work, ['rig_sim'], [3.0], rate),
        *restarts(work, ['analyzer'], rate),
        early_trigger(work, rate),
        unit_run(work, {'force': 'kN', 'velocity': 'in/s'}, rate),
    ]


def report(rows: list[Outcome]) -> str:
    return '\n'.join([HEADER, *(row.row() for row in rows)])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='a few short faults (CI)')
    args = parser.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix='fault_rig_'))
    rate = RATE
    print(HEADER, flush=True)
    try:
        if args.quick:
            rows = quick_rows(work)
        else:
            rows = [
                *stalls(work, ['rig_sim', 'analyzer'], [1.0, 5.0, 15.0, 30.0], rate),
                *stalls(work, ['hammer_sim', 'fitter', 'recorder'], [15.0], rate),
                *restarts(work, SIMULATED_RIG, rate),
                early_trigger(work, rate),
                *units(work, list(FORCE_UNITS)[1:], list(VELOCITY_UNITS)[1:], rate),
                two_sources(work, rate),
                disk_full(work, rate),
            ]
    finally:
        shutil.rmtree(work, ignore_errors=True)
    table = report(rows)
    print(f'load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores, x{rate:g}')
    write_section('fault_rig', table, quick=args.quick)
    return 0


if __name__ == '__main__':
    sys.exit(main())
