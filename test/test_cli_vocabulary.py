"""One vocabulary across `fmm`: -o/--output for results, SI units in
every flag name, the same hit selection on analyze/fit/diagnose/report, one spelling per
option (the old ones and prefixes refused), -q on every long job and progress only on a
terminal, a quiet end on a closed pipe. And the CLI's shape: subcommands import
no other subcommand, the report computes nothing."""

import argparse
import ast
import io
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from fit_records import lab_levels

from fmm_ros.cli import SUBCOMMANDS, build_parser, main
from fmm_ros.cli.progress import StatusLine
from fmm_ros.core.signal.records import write_impact_csv
from fmm_ros.io.bags import BagWriter

REPO = Path(__file__).resolve().parents[1]
# Options whose values carry no unit, or carry it in words of their own.
DIMENSIONLESS = {
    '--mu',
    '--mu-min',
    '--mu-max',
    '--plant-mu',
    '--rate-factor',
    '--dpi',
    '--force-scale',  # SI units per file unit: the unit is the file's
    '--velocity-scale',
    '--acceleration-scale',
    '--displacement-scale',
}
SI_SUFFIXES = ('-n', '-s', '-hz', '-kg', '-m', '-m-s', '-m-s2', '-n-per-m', '-n-s-per-m')
HIT_SELECTION = {
    '--paper-levels',
    '--level',
    '--tolerance-n',
    '--trigger-n',
    '--rearm-n',
    '--window-s',
    '--rest-velocity-m-s',
    '--reject',
}


def subparsers() -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def visible_options(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    return {
        option: action
        for action in parser._actions
        if action.help != argparse.SUPPRESS
        for option in action.option_strings
    }


def test_every_number_flag_names_its_si_unit():
    offending = []
    for command, parser in subparsers().items():
        for option, action in visible_options(parser).items():
            if option.startswith('--') and action.type is float and option not in DIMENSIONLESS:
                if not option.endswith(SI_SUFFIXES):
                    offending.append(f'fmm {command} {option}')
    assert offending == []


def test_results_go_to_o_output_everywhere():
    for command in ('analyze', 'replay', 'report', 'diagnose', 'demo', 'simulate', 'import'):
        options = visible_options(subparsers()[command])
        assert {'-o', '--output'} <= set(options), command
        for old in ('--out', '--export', '--plot'):
            assert old not in options, f'fmm {command} still shows {old}'


def test_analyze_fit_diagnose_and_report_select_hits_alike():
    for command in ('analyze', 'fit', 'diagnose', 'report', 'replay'):
        assert HIT_SELECTION <= set(visible_options(subparsers()[command])), command


def test_every_long_job_takes_quiet():
    for command in (
        'analyze',
        'fit',
        'diagnose',
        'identify-rig',
        'report',
        'replay',
        'import',
        'bag-info',
    ):
        assert {'-q', '--quiet'} <= set(visible_options(subparsers()[command])), command


@pytest.fixture(scope='module')
def levels_csv(tmp_path_factory):
    folder = tmp_path_factory.mktemp('vocabulary')
    paths = []
    for number, record in enumerate(lab_levels(11, mu=0.113, duration_s=6.0)):
        paths.append(folder / f'{number}.csv')
        write_impact_csv(paths[-1], record.force_n, record.velocity_m_s, record.sample_rate_hz)
    return paths


def test_old_spellings_are_refused(levels_csv, capsys):
    for argv in (
        ['analyze', str(levels_csv[0]), '--export', 'a.csv'],
        ['diagnose', str(levels_csv[0]), '--plot', 'dir'],
        ['simulate', '--x0-mm', '3'],
        ['fit', str(levels_csv[0]), '--band-limit-hz', '15'],
        ['import', str(levels_csv[0]), '--force-full-scale', '1000'],
        ['report', str(levels_csv[0]), '--out', 'dir'],
    ):
        with pytest.raises(SystemExit):
            build_parser().parse_args(argv)
        assert 'unrecognized arguments' in capsys.readouterr().err, argv


def test_import_full_scale_flag_is_in_si_and_the_mapping_one_in_file_units(tmp_path):
    path = tmp_path / 'hit.csv'
    np.savetxt(
        path,
        np.column_stack([np.arange(600) / 1e4, np.zeros(600), np.zeros(600)]),
        delimiter=',',
        header='Time,Hammer,Vibrometer\ns,lbf,mm/s',
        comments='',
    )
    mapping = tmp_path / 'mapping.yaml'
    mapping.write_text('force: {name: Hammer, unit: lbf, full_scale: 1000}\n')
    from fmm_ros.io.bags import BagReader

    full_scales = []
    for name, flags in (
        ('si', ['--force-full-scale-n', '4448.2216152605']),
        ('file_units', ['-m', str(mapping)]),
    ):
        bag = tmp_path / name
        assert main(['import', str(path), '-o', str(bag), *flags]) == 0
        with BagReader(bag) as reader:
            full_scales.append(next(reader.batches()).full_scale_force)
    assert full_scales == pytest.approx([4448.2216152605, 4448.2216152605])


@pytest.mark.slow
def test_fit_selects_the_accepted_hits_when_asked(levels_csv, tmp_path, capsys):
    out_of_levels = tmp_path / 'stray.csv'
    record = lab_levels(12, mu=0.113, duration_s=6.0, levels=('medium',))[0]
    write_impact_csv(
        out_of_levels, record.force_n * 0.7, record.velocity_m_s * 0.7, record.sample_rate_hz
    )
    inputs = [*map(str, levels_csv), str(out_of_levels)]
    assert main(['fit', *inputs, '--json']) == 0
    assert len(json.loads(capsys.readouterr().out)['per_file']) == 4
    assert main(['fit', *inputs, '--json', '--paper-levels']) == 0
    fitted = json.loads(capsys.readouterr().out)['per_file']
    assert [entry['file'] for entry in fitted] == [str(path) for path in levels_csv]
    # Each hit is fitted under the id `fmm analyze` gives it: its time on the session's axis.
    assert main(['analyze', *inputs, '--json']) == 0
    analyzed = {
        hit['file']: hit['impact_id'] for hit in json.loads(capsys.readouterr().out)['impacts']
    }
    assert [entry['impact_id'] for entry in fitted] == [analyzed[str(p)] for p in levels_csv]


class Terminal(io.StringIO):
    """A stderr that says it is a terminal."""

    def isatty(self):
        return True


def test_progress_shows_on_a_terminal_only_and_json_is_unchanged(levels_csv, capsys, monkeypatch):
    terminal = Terminal()
    monkeypatch.setattr(sys, 'stderr', terminal)
    assert main(['fit', *map(str, levels_csv), '--json']) == 0
    shown = capsys.readouterr().out
    monkeypatch.setattr(sys, 'stderr', Terminal())
    assert main(['fit', *map(str, levels_csv), '--json', '-q']) == 0
    quiet = capsys.readouterr().out
    assert json.loads(shown) == json.loads(quiet)
    assert 'reading 0.csv (1/3)' in terminal.getvalue()
    assert sys.stderr.getvalue() == ''  # -q


def test_a_status_line_shows_each_step_and_the_clock(monkeypatch):
    monkeypatch.setattr('fmm_ros.cli.progress.REFRESH_S', 0.05)
    terminal = Terminal()
    with StatusLine(quiet=False, stream=terminal) as progress:
        progress('fitting one mu to 3 impacts')
        time.sleep(0.2)
        progress('fitting mu of impact 1/3 alone')
        time.sleep(0.2)
    shown = terminal.getvalue()
    assert 'fitting one mu to 3 impacts [00:00]' in shown
    assert 'fitting mu of impact 1/3 alone' in shown
    silent = io.StringIO()  # not a terminal
    with StatusLine(quiet=False, stream=silent) as progress:
        progress('anything')
    assert silent.getvalue() == ''


@pytest.mark.slow
def test_a_closed_pipe_ends_quietly(tmp_path):
    bag = tmp_path / 'bag'
    with BagWriter(bag) as writer:
        writer.write_signals(np.zeros(20_000), np.zeros(20_000), 10_000.0)
    fmm = Path(sys.executable).with_name('fmm')
    for command in (['bag-info', str(bag), '--json'], ['bag-info', str(bag)]):
        process = subprocess.Popen(
            [str(fmm), *command], stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
        process.stdout.close()  # as `| head -0` does: the reader is gone before any output
        _, err = process.communicate(timeout=120)
        assert b'Traceback' not in err and b'BrokenPipe' not in err, err.decode()
        assert process.returncode == 141


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            found.add(node.module)
            found.update(f'{node.module}.{alias.name}' for alias in node.names)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return found


def test_no_subcommand_imports_another():
    commands = {f'fmm_ros.cli.{name}' for name in SUBCOMMANDS.values()}
    for name in SUBCOMMANDS.values():
        path = REPO / 'fmm_ros' / 'cli' / f'{name}.py'
        others = _imports(path) & (commands - {f'fmm_ros.cli.{name}'})
        assert others == set(), f'cli/{name}.py imports {others}'


def test_the_session_report_fits_diagnoses_and_simulates_nothing():
    forbidden = ('fmm_ros.core.identify', 'fmm_ros.core.physics')
    diagnose = 'fmm_ros.core.diagnose.workflow.diagnose'
    for name in ('session.py', 'session_figures.py', 'diagnosis_figures.py', 'html.py'):
        imported = _imports(REPO / 'fmm_ros' / 'report' / name)
        bad = [m for m in imported if m.startswith(forbidden) or m == diagnose]
        assert bad == [], f'report/{name} imports {bad}'
