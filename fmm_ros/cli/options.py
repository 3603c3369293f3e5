"""The option groups the subcommands share, so every one spells a thing the same way.

- `add_inputs`: INPUTs (lab files and bags, `fmm_ros.workflows.inputs`) with the channel
  mapping of `fmm import` (`-m/--mapping`, `--force NAME`, `--force-unit`, ...) and the text
  layout (`--delimiter`, `--decimal`, `--skip-rows`, `--encoding`);
- `add_hit_selection`: how hits are cut, grouped and judged (`--paper-levels`, `--level`,
  `--window-s`, `--reject`, ...), the same on analyze, fit, diagnose, report and replay;
- `add_model`: the rig constants and what a friction fit frees besides mu;
- `add_output`: `-o/--output`, where results go;
- `add_quiet`, `add_json`.

Options that set a core setting are made from its declaration (`add_setting`: the field's
default, unit, help and limits in `fmm_ros.core.settings`), so they say what the ROS
parameters and the docs say. This module imports no numerics: `fmm --help` answers at once;
the readers and workflows are imported by the functions that build their options.

Units are SI and named in every flag (`--force-full-scale-n`); each option has one spelling.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fmm_ros.constants import RESPONSE_CHANNELS
from fmm_ros.core.identify.spec import FitSpec
from fmm_ros.core.physics.rig import Rig
from fmm_ros.core.settings import Setting, setting_of, settings_of
from fmm_ros.core.signal.config import (
    FLAGS,
    AnalysisConfig,
    CaptureConfig,
    NominalLevel,
    SensorRanges,
    paper_levels,
)
from fmm_ros.io.textformat import TextFormat, delimiter_from_name

if TYPE_CHECKING:
    from fmm_ros.workflows.inputs import InputOptions
    from fmm_ros.workflows.session import FitOptions

QUANTITIES = ('force', *(channel.quantity for channel in RESPONSE_CHANNELS))
# The SensorRanges field of each quantity's range: `force_full_scale_n`.
FULL_SCALE_DESTS = {
    quantity: next(
        item.name for item in settings_of(SensorRanges) if item.name.startswith(quantity)
    )
    for quantity in QUANTITIES
}


def add_setting(
    group,
    cls: type,
    name: str,
    *,
    help: str | None = None,
    flag: str | None = None,
    **kwargs: Any,
) -> argparse.Action:
    """The option of a declared setting: its flag, type, default, choices, unit and help.

    help replaces the declared help (the unit and default are still added); flag another
    spelling than the declared one (the dest follows it); kwargs go to add_argument (a
    different default, a metavar, a type that parses the text).
    """
    item = setting_of(cls, name)
    default = kwargs.pop('default', item.default)
    kind = type(item.default) if item.default is not None else str if item.choices else float
    options: dict[str, Any] = {'type': kind, 'default': default}
    if kind is bool:
        options = {'action': argparse.BooleanOptionalAction, 'default': default}
    elif kind is str and item.choices:
        options['choices'] = item.choices
    options.update(kwargs)
    return group.add_argument(
        flag or item.option, **options, help=setting_help(item, help, default)
    )


def add_range_setting(
    group, cls: type, name: str, flags: tuple[str, str], *, default: tuple | None = None
) -> None:
    """The two options of a declared (low, high) setting, one an end (`--mu-min`, `--mu-max`).

    default: other ends than the declared ones (a client's 0, 0 for "the server's").
    """
    item = setting_of(cls, name)
    ends = item.default if default is None else default
    for end, flag, value in zip(('lower', 'upper'), flags, ends, strict=True):
        group.add_argument(
            flag,
            type=type(value),
            default=value,
            help=setting_help(item, f'{end} end: {item.help[:1].lower()}{item.help[1:]}', value),
        )


def setting_help(item: Setting, help: str | None, default: Any) -> str:
    """'Force that starts an impact [N] (default 20)': a setting's help as --help shows it."""
    initial = item.help[:1] if item.help[1:2].isupper() else item.help[:1].lower()  # PNG stays
    text = help or initial + item.help[1:]
    if item.unit:
        text += f' [{item.unit}]'
    shown = 'none' if default is None else f'{default:g}' if isinstance(default, float) else default
    shown = "''" if shown == '' else shown
    return f'{text} (default {shown})'


# -- inputs ------------------------------------------------------------------------------------


def add_inputs(parser: argparse.ArgumentParser, *, nargs: str = '+', what: str = 'impact') -> None:
    """INPUTs and how lab files among them are read (mapping, text layout, full scales)."""
    parser.add_argument(
        'inputs',
        nargs=nargs,
        type=Path,
        metavar='INPUT',
        help=f'lab files (CSV/TSV/TXT, NPZ, MATLAB .mat, TDMS), one {what} each, or bags '
        '(directory, .mcap or .db3) of every impact recorded; told apart by content',
    )
    add_lab_file_reading(parser)


def add_lab_file_reading(parser: argparse.ArgumentParser) -> None:
    """How lab files are read (mapping, text layout, full scales, continuous): add_inputs'."""
    group = parser.add_argument_group(
        'reading lab files',
        'Which channel is force, the response (velocity, acceleration or displacement) and '
        'time, in which unit, at which rate: stated here or in a mapping file (as fmm '
        'import), else taken from the file where it says so (names time_s, force_n, '
        'velocity_m_s, acceleration_m_s2, displacement_m; a units row; "Hammer [lbf]"; TDMS '
        'units).',
    )
    add_mapping_flags(group)
    add_full_scale_flags(group)
    group.add_argument(
        '--continuous',
        action='store_true',
        help='each lab file is one recording of several hits: cut every impact as from a bag '
        '(default: a lab file is one impact record)',
    )


def add_mapping_flags(group) -> None:
    """-m/--mapping, the channel flags, the rate and the text layout (shared with import)."""
    group.add_argument('-m', '--mapping', type=Path, help='YAML mapping file (see fmm import -h)')
    for quantity in (*QUANTITIES, 'time'):
        group.add_argument(
            f'--{quantity}',
            metavar='NAME',
            help=f'{quantity} column, variable (struct.field) or TDMS group/channel',
        )
        group.add_argument(
            f'--{quantity}-unit', metavar='UNIT', help=f'unit of {quantity} in the file'
        )
    for quantity in QUANTITIES:
        group.add_argument(
            f'--{quantity}-scale',
            type=float,
            metavar='SI_PER_UNIT',
            help=f'SI units per file unit, for a sensor unit of {quantity} (V, counts)',
        )
    group.add_argument(
        '--sample-rate-hz',
        metavar='HZ_OR_VARIABLE',
        help='sample rate, or the name of the variable holding it (default: from a time '
        'channel, a sample_rate_hz variable or the TDMS increments)',
    )
    add_setting(group, TextFormat, 'delimiter', type=_delimiter)
    add_setting(group, TextFormat, 'decimal')
    add_setting(group, TextFormat, 'skip_rows', metavar='N')
    add_setting(group, TextFormat, 'encoding', type=str)


def add_full_scale_flags(group) -> None:
    """--force-full-scale-n and the response sensors' ranges (SI), for the clipped flags."""
    for name in FULL_SCALE_DESTS.values():
        add_setting(group, SensorRanges, name, metavar=name.rsplit('_scale_', 1)[1].upper())


def mapping_spec(args: argparse.Namespace) -> dict:
    """The mapping file's entries with the flags laid over them (flags win), in YAML form."""
    from fmm_ros.io.labfiles import CHANNEL_KEYS, load_mapping

    spec = load_mapping(args.mapping) if getattr(args, 'mapping', None) else {}
    for quantity in (*QUANTITIES, 'time'):
        entry = spec.get(quantity)
        entry = {'name': entry} if isinstance(entry, str | int) else dict(entry or {})
        flags = {
            'name': getattr(args, quantity, None),
            'unit': getattr(args, f'{quantity}_unit', None),
            'scale': getattr(args, f'{quantity}_scale', None),
            'full_scale_si': getattr(args, FULL_SCALE_DESTS.get(quantity, ''), None) or None,
        }
        entry.update({key: value for key, value in flags.items() if value is not None})
        if entry:
            spec[quantity] = {key: entry[key] for key in CHANNEL_KEYS if key in entry}
    rate = getattr(args, 'sample_rate_hz', None)
    if rate is not None:
        try:
            spec['sample_rate_hz'] = float(rate)
        except ValueError:
            spec['sample_rate_hz'] = rate
    return spec


def text_format(args: argparse.Namespace) -> TextFormat:
    """How text files are laid out, as far as the flags say."""
    return TextFormat(args.delimiter, args.decimal, args.skip_rows, args.encoding)


def input_options(args: argparse.Namespace, capture: CaptureConfig | None = None) -> InputOptions:
    """The InputOptions of the flags add_inputs added (and the capture of the hit options).

    Where the hit options name no levels, the bags' recorded levels are read with the
    inputs (`recorded_level_tolerance`), to be laid over the analysis by
    `SessionInputs.grouped`.
    """
    from fmm_ros.workflows.inputs import InputOptions

    return InputOptions(
        mapping=mapping_spec(args),
        text_format=text_format(args),
        capture=capture or CaptureConfig(),
        ranges=SensorRanges(**{name: getattr(args, name) for name in FULL_SCALE_DESTS.values()}),
        continuous=args.continuous,
        level_tolerance_n=recorded_level_tolerance(args) if getattr(args, 'inputs', None) else None,
    )


# -- hit selection -------------------------------------------------------------------------------


def add_hit_selection(parser: argparse.ArgumentParser, *, fits: bool = False) -> None:
    """How hits are cut from recordings, grouped into levels and judged.

    fits: the command fits or diagnoses the hits (fit, diagnose, report): only the accepted
    ones, the others named, unless --include-flagged (`select_impacts`).
    """
    group = parser.add_argument_group(
        'hit selection',
        'How impacts are cut from recordings, grouped into force levels (without levels given, '
        "a bag's as its analyzer named them, else clustered peak forces) and judged"
        + (
            '. Only the accepted hits are fitted; the others are left out and named '
            '(--include-flagged takes them too).'
            if fits
            else '.'
        ),
    )
    levels = group.add_mutually_exclusive_group()
    levels.add_argument(
        '--level',
        action='append',
        default=[],
        metavar='NAME=FORCE_N',
        type=_nominal_level,
        help='a nominal force level (repeatable); without levels, peak forces are clustered',
    )
    levels.add_argument(
        '--paper-levels',
        action='store_true',
        help="the paper's levels: low=450, medium=1000, high=1450 N",
    )
    add_setting(group, NominalLevel, 'tolerance_n')
    add_setting(group, CaptureConfig, 'trigger_level_n')
    add_setting(group, CaptureConfig, 'rearm_level_n')
    add_setting(
        group,
        CaptureConfig,
        'window_s',
        help='record length cut from a bag or continuous file, pre-trigger included (33 s in '
        'the paper)',
    )
    add_setting(group, CaptureConfig, 'rest_velocity_m_s')
    add_setting(
        group,
        AnalysisConfig,
        'reject_flags',
        flag='--reject',
        type=_flag_list,
        default=None,
        metavar='FLAG,...',
        help=f'flags that reject an impact, or "none" (none given: all of {",".join(FLAGS)})',
    )
    if fits:
        group.add_argument(
            '--include-flagged',
            action='store_true',
            help='also fit the hits the flags reject (clipped, double hit, dead vibrometer, '
            '...), with a warning; by default they are left out and named',
        )


def add_frf_options(parser: argparse.ArgumentParser) -> None:
    """The FRFs' band and windows (analyze, replay, report)."""
    group = parser.add_argument_group('frequency response functions')
    for name in ('band_limit_hz', 'force_window_s', 'exponential_decay_s'):
        add_setting(group, AnalysisConfig, name)


def add_analysis(parser: argparse.ArgumentParser) -> None:
    """What analyze and replay share: --json, -o for the level FRFs, hits, FRFs, --quiet."""
    add_json(parser, 'one object')
    add_output(
        parser,
        'write the level FRFs to PATH: .uff/.unv (UFF 58), .csv or .json (repeatable)',
        repeat=True,
    )
    add_hit_selection(parser)
    add_frf_options(parser)
    add_quiet(parser)


def analysis_configs(args: argparse.Namespace) -> tuple[CaptureConfig, AnalysisConfig]:
    """The capture and analysis configuration of add_hit_selection's (and add_frf_options').

    Opens no file: the levels are those the flags name (none: a bag's recorded levels, read
    with the inputs where `recorded_level_tolerance` says so, else clustered peak forces).
    """
    capture = CaptureConfig(
        trigger_level_n=args.trigger_n,
        rearm_level_n=args.rearm_n,
        rest_velocity_m_s=args.rest_velocity_m_s,
        window_s=args.window_s,
    )
    levels = (
        paper_levels(args.tolerance_n)
        if args.paper_levels
        else tuple(dataclasses.replace(level, tolerance_n=args.tolerance_n) for level in args.level)
    )
    frf = AnalysisConfig()
    analysis = AnalysisConfig(
        band_limit_hz=getattr(args, 'band_limit_hz', frf.band_limit_hz),
        force_window_s=getattr(args, 'force_window_s', None),
        exponential_decay_s=getattr(args, 'exponential_decay_s', None),
        levels=levels,
        reject_flags=FLAGS if args.reject is None else args.reject,
    )
    return capture, analysis


def recorded_level_tolerance(args: argparse.Namespace) -> float | None:
    """The tolerance [N] of a bag's recorded levels, where the hit options name no levels.

    A bag's levels keep the names its analyzer gave them (low, medium, high); None for a
    command without the hit options, or levels given.
    """
    if not hasattr(args, 'paper_levels') or args.paper_levels or args.level:
        return None
    return args.tolerance_n


def _nominal_level(text: str) -> NominalLevel:
    """NAME=FORCE_N from the command line."""
    name, _, force = text.partition('=')
    try:
        value = float(force)
    except ValueError:
        value = math.nan
    if not name.strip() or not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(
            f'expected NAME=FORCE_N with a positive force, got {text!r}'
        )
    return NominalLevel(name.strip(), value)


def _flag_list(text: str) -> tuple[str, ...]:
    """A comma-separated flag list, or "none"."""
    if text.strip().lower() == 'none':
        return ()
    flags = tuple(flag.strip() for flag in text.split(',') if flag.strip())
    unknown = [flag for flag in flags if flag not in FLAGS]
    if unknown:
        raise argparse.ArgumentTypeError(
            f'unknown flag(s) {", ".join(unknown)}; known: {", ".join(FLAGS)}'
        )
    return flags


def _delimiter(text: str) -> str:
    try:
        return delimiter_from_name(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


# -- the model -----------------------------------------------------------------------------------


def add_rig(parser: argparse.ArgumentParser) -> None:
    """--mass-kg, --stiffness-n-per-m, --damping-n-s-per-m, --normal-force-n (FMM defaults)."""
    group = parser.add_argument_group('rig constants (default: the FMM)')
    for item in dataclasses.fields(Rig):
        add_setting(group, Rig, item.name)


def add_model(parser: argparse.ArgumentParser, *, damping: bool = True) -> None:
    """The rig constants and what a friction fit frees besides mu."""
    add_rig(parser)
    group = parser.add_argument_group('what the fit frees besides mu')
    if damping:
        add_setting(group, FitSpec, 'fit_damping')
    # A session's hits find the rig where friction left it after the one before: on by default.
    add_setting(group, FitSpec, 'fit_initial_position', default=True)
    add_setting(group, FitSpec, 'chain_starts')


def rig_from_args(args: argparse.Namespace) -> Rig:
    """The Rig the rig flags describe (ValueError naming a bad constant)."""
    return Rig(
        mass_kg=args.mass_kg,
        stiffness_n_per_m=args.stiffness_n_per_m,
        damping_n_s_per_m=args.damping_n_s_per_m,
        normal_force_n=args.normal_force_n,
    )


def fit_options(args: argparse.Namespace) -> FitOptions:
    """The FitOptions of the model flags (and fmm fit's own, where present)."""
    from fmm_ros.workflows.session import FitOptions

    extra = {}
    if hasattr(args, 'mu_min'):
        extra = {
            'mu_bounds': (args.mu_min, args.mu_max),
            'misfit': args.misfit,
            'band_limit_hz': args.misfit_band_limit_hz,
        }
    return FitOptions(
        rig=rig_from_args(args),
        fit_damping=getattr(args, 'fit_damping', False),
        fit_initial_position=args.fit_initial_position,
        chain_starts=args.chain_starts,
        **extra,
    )


# -- output --------------------------------------------------------------------------------------


def add_output(
    parser: argparse.ArgumentParser,
    help: str,
    *,
    metavar: str = 'PATH',
    repeat: bool = False,
    **kwargs,
) -> None:
    """-o/--output (repeatable if repeat)."""
    options = {'action': 'append', 'default': []} if repeat else {'default': None}
    parser.add_argument(
        '-o', '--output', type=Path, metavar=metavar, help=help, **options, **kwargs
    )


def add_whole_record(parser: argparse.ArgumentParser, *, fit_rig: bool = True) -> None:
    """--whole-record (each file one excitation) and --fit-rig (m, c, k from the record)."""
    group = parser.add_argument_group(
        'whole records',
        'A record that is not a set of hits (random or multisine excitation, a sweep, a '
        'closed-loop move): name --force and --displacement (and their units; V is analysed '
        'per V) and --sample-rate-hz or --time.',
    )
    group.add_argument(
        '--whole-record',
        action='store_true',
        help='each file is one excitation, its measured force driving the model throughout',
    )
    if fit_rig:
        group.add_argument(
            '--fit-rig',
            action='store_true',
            help='with --whole-record: fit m, c, k from the record (the rig is unknown); '
            'otherwise the rig constants are used',
        )


def add_json(parser: argparse.ArgumentParser, what: str = 'the result') -> None:
    """--json: print one JSON document on stdout instead of text."""
    parser.add_argument('--json', action='store_true', help=f'print {what} as JSON')


def add_quiet(parser: argparse.ArgumentParser) -> None:
    """-q/--quiet: no progress display (there is none anyway when stderr is not a terminal)."""
    parser.add_argument(
        '-q',
        '--quiet',
        action='store_true',
        help='no progress display (there is none anyway when stderr is not a terminal)',
    )
