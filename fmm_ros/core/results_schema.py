"""One declaration per result field: name, unit, description, label and format, written once.

Every result the package shows (an impact, a force level, a friction fit, a diagnosis) is
made of fields declared here, each a `ResultField`: the key (the dataclass attribute, the JSON
key, the message field, the CSV and tidy-table column), the SI unit as the .msg comments
write it, the description, the words a table or an axis shows, the unit and factor it is
shown in, and the format of a table cell. What shows a field reads it from here:

- `label(field)`: 'impulse [N·s]', the one rule for a heading or an axis: the field's words,
  then its shown unit in brackets, typographic ('N·s', 'mm/(N²·s)') for pages and figures,
  `ascii=True` for terminal text ('impulse [N*s]');
- `keys(fields)`: JSON key and column lists (`workflows.results`, the campaign's tables);
- `IMPACT`, `LEVEL`, `FIT`, `DIAGNOSIS`: the groups, by key;
- `format_with_uncertainty(value, std)`: the one rule a value is printed with its
  uncertainty by: the value to the second significant digit of the uncertainty.

The result dataclasses of the core (`ImpactAnalysis`, `LevelSummary`) take each field's unit
and help from here (`ResultField.field()`), so the reference docs say what the JSON, the
messages and the tables hold. `test/test_results_schema.py` holds the .msg/.srv comments to
the units declared here and names any drift.

`impact_id` (`IMPACT_ID`) means one thing everywhere: the hit's trigger time in ms modulo
2^32 on its session's time axis, made by `core.signal.records.stable_impact_id` alone (the
analyzer, `fmm replay`, the fitter's selections, the recorder's bags, the station, and the
offline `fmm analyze`, `fit`, `report`, `campaign`), so a hit keeps its id across a respawn,
a replay and an offline read. A bag with an acquisition clock uses its clock. Inputs without
one (lab files, bags written without a clock) are laid end to end in the order given on one
session axis (`workflows.inputs`), so their ids depend on that order; two hits of a session
that would share an id are refused, naming both inputs (`workflows.session.impact_ids`).
Code that indexes records uses a position, named as one.

Standard library only: `fmm --help`, the station page and the docs read it without numpy.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from fmm_ros.constants import MM_PER_M, RECEPTANCE_DISPLAY_UNIT
from fmm_ros.core.settings import result_field

_TYPOGRAPHIC = (('^2', '²'), ('*', '·'))
"""ASCII unit spelling -> the typographic one pages and figures show."""


@dataclass(frozen=True)
class ResultField:
    """One field of a result: key, unit, description, shown words, shown unit, cell format.

    unit: the SI unit as the .msg comments write it ('N*s'); '-' for a dimensionless number
    or a count, '' for a name, a flag list or a truth value. words: what a heading or an
    axis calls it ('impulse'). shown_unit/shown_factor: the unit a table or figure shows it
    in and the factor from SI (receptance in mm/N: 1e3); empty: the SI unit. fmt: the format
    spec of a table cell. short: the words of a narrow terminal column ('peak'). messages:
    the .msg/.srv fields that carry it ('ImpactResult.impulse_n_s').
    limits: the range a valid value lies in (inclusive), where one is known.
    """

    name: str
    unit: str
    help: str
    words: str
    fmt: str = '.4g'
    shown_unit: str = ''
    shown_factor: float = 1.0
    messages: tuple[str, ...] = ()
    limits: tuple[float, float] | None = None
    short: str = ''

    @property
    def display_unit(self) -> str:
        """The unit a table or figure shows the field in (ASCII spelling)."""
        return self.shown_unit or self.unit

    def shown(self, value: float) -> float:
        """The value in the shown unit (receptance in mm/N)."""
        return value * self.shown_factor

    def cell(self, value: float, spec: str = '') -> str:
        """The value in the shown unit, formatted by the field's (or the given) spec."""
        return format(self.shown(value), spec or self.fmt)

    def field(self) -> Any:
        """A dataclass field without a default that carries this unit and help (settings_of)."""
        return result_field(help=self.help, unit=self.unit if self.unit not in ('', '-') else '')


def typographic(unit: str) -> str:
    """'N*s' -> 'N·s', 'm/(N^2*s)' -> 'm/(N²·s)': a unit as pages and figures write it."""
    for ascii_text, shown in _TYPOGRAPHIC:
        unit = unit.replace(ascii_text, shown)
    return unit


def label(field: ResultField, *, ascii: bool = False, short: bool = False, words: str = '') -> str:
    """The one heading rule: 'impulse [N·s]' (`ascii`: 'impulse [N*s]'); no unit, no brackets.

    short: the field's short words where it has them (a narrow terminal column); words:
    other words for the same field and unit (a figure's 'impulse I').
    """
    unit = field.display_unit if field.display_unit not in ('', '-') else ''
    text = words or (short and field.short) or field.words
    if not unit:
        return text
    return f'{text} [{unit if ascii else typographic(unit)}]'


def keys(fields: tuple[ResultField, ...]) -> tuple[str, ...]:
    """The JSON keys (and column names) of these fields, in order."""
    return tuple(field.name for field in fields)


ASCII_PM = ' +- '
"""The separator of a value and its uncertainty in terminal text and logs (pages use ' ± ')."""


def format_with_uncertainty(value: float, std: float, sep: str = ' ± ') -> str:
    """'0.1130004 ± 0.0000014': the value to the second significant digit of its uncertainty.

    Both are printed with the same number of decimals, so the last digit shown of the value
    is the uncertainty's second significant one. Without a finite positive uncertainty the
    value alone, to 5 significant digits. sep: ASCII_PM for terminal text and logs.
    """
    if not (math.isfinite(value) and math.isfinite(std) and std > 0):
        return f'{value:.5g}'
    decimals = min(12, max(0, 1 - math.floor(math.log10(std))))
    return f'{value:.{decimals}f}{sep}{std:.{decimals}f}'


def _group(*fields: ResultField) -> dict[str, ResultField]:
    return {field.name: field for field in fields}


# -- an impact ---------------------------------------------------------------------------------

IMPACT_ID = ResultField(
    'impact_id',
    '-',
    "The impact's id: its trigger's acquisition time in ms modulo 2^32"
    " (`records.stable_impact_id`) on its session's time axis: the acquisition clock where the"
    ' hit has one (live and offline alike); inputs without a clock laid end to end in the order'
    ' given, so there the id depends on that order',
    'hit',
    fmt='d',
    messages=('ImpactResult.impact_id', 'FitFriction.impact_ids', 'FrictionEstimate.impact_id'),
)
TRIGGER_SAMPLE_INDEX = ResultField(
    'trigger_sample_index',
    'samples',
    'Sample index of the force trigger in its acquisition',
    'trigger',
    fmt='d',
    messages=('ImpactResult.trigger_sample_index',),
)
RECORD_START_SAMPLE_INDEX = ResultField(
    'record_start_sample_index',
    'samples',
    "Sample index of the analysed record's first sample (trigger minus pre-trigger)",
    'record start',
    fmt='d',
    messages=('ImpactResult.record_start_sample_index',),
)
LEVEL = ResultField(
    'level',
    '',
    'Force level the impact belongs to; empty: none',
    'level',
    fmt='s',
    messages=('ImpactResult.level',),
)
ACCEPTED = ResultField(
    'accepted',
    '',
    'Whether it enters the level averages: no rejecting flag, its numbers determined',
    'ok',
    fmt='',
    messages=('ImpactResult.accepted',),
)
FLAGS = ResultField(
    'flags',
    '',
    'Quality flags it raised, in FLAGS order',
    'flags',
    fmt='s',
    messages=('ImpactResult.flags',),
)
IMPULSE = ResultField(
    'impulse_n_s',
    'N*s',
    'Impulse: the area under the force pulse by the trapezoid rule, baseline removed',
    'impulse',
    messages=('ImpactResult.impulse_n_s', 'FitFriction.per_impact_impulse_n_s'),
    limits=(0.0, math.inf),
)
PEAK_FORCE = ResultField(
    'peak_force_n',
    'N',
    'Largest force during contact',
    'peak force',
    short='peak',
    messages=('ImpactResult.peak_force_n',),
)
CONTACT_DURATION = ResultField(
    'contact_duration_s',
    's',
    "Time the force stays above the contact threshold (the capture's re-arm level)",
    'contact',
    fmt='.3g',
    shown_unit='ms',
    shown_factor=1e3,
    messages=('ImpactResult.contact_duration_s',),
    limits=(0.0, math.inf),
)
RECORD_DURATION = ResultField(
    'record_duration_s',
    's',
    'Length of the analysed record: the capture window',
    'record',
    messages=('ImpactResult.record_duration_s',),
)
SAMPLE_RATE = ResultField(
    'sample_rate_hz',
    'Hz',
    'Sampling rate of both channels of the record',
    'sample rate',
    fmt='g',
    messages=('ImpactResult.sample_rate_hz',),
)
NATURAL_FREQUENCY = ResultField(
    'natural_frequency_hz',
    'Hz',
    'Natural frequency of the rig, from the period between velocity reversals, or for a ring'
    ' too short for them (one or two cycles) from its DFT peak; NaN when the record has no peak',
    'f_n',
    fmt='.4f',
    messages=('ImpactResult.natural_frequency_hz', 'FrfSummary.natural_frequency_hz'),
)
NATURAL_FREQUENCY_METHOD = ResultField(
    'natural_frequency_method',
    '',
    "How f_n was found: 'reversals' (the period between velocity reversals), 'dft_peak' (the"
    " peak of a short ring's spectrum, `frf.dft_peak_frequency`); empty when it was not",
    'f_n from',
    fmt='s',
    messages=('ImpactResult.natural_frequency_method', 'FrfSummary.natural_frequency_method'),
)
NATURAL_FREQUENCY_UNCERTAINTY = ResultField(
    'natural_frequency_uncertainty_hz',
    'Hz',
    'Uncertainty of an f_n read at a DFT peak: the bound on how far a ring this short moves'
    " its spectrum's peak, combined with the noise's standard deviation"
    ' (`frf.dft_peak_frequency`); NaN for f_n timed by reversals (good to about 1e-3)',
    'f_n uncertainty',
    fmt='.2g',
    messages=('ImpactResult.natural_frequency_uncertainty_hz',),
)
PEAK_RECEPTANCE = ResultField(
    'peak_receptance_m_per_n',
    'm/N',
    'Largest |receptance| in the peak band',
    'peak |X/F|',
    short='|X/F|',
    shown_unit=RECEPTANCE_DISPLAY_UNIT,
    shown_factor=MM_PER_M,
    messages=('ImpactResult.peak_receptance_m_per_n', 'FrfSummary.peak_receptance_m_per_n'),
)
FREQUENCY_STEP = ResultField(
    'frequency_step_hz',
    'Hz',
    'FRF frequency resolution: 1 / record length',
    'frequency step',
    messages=('ImpactResult.frequency_step_hz', 'FrfSummary.frequency_step_hz'),
)
FORCE_WINDOW = ResultField(
    'force_window_s',
    's',
    'Force window the FRF was computed with; 0: none',
    'force window',
    messages=('ImpactResult.force_window_s',),
)
EXPONENTIAL_WINDOW_DECAY = ResultField(
    'exponential_window_decay_s',
    's',
    'Exponential window decay time the FRF was computed with; 0: none',
    'exponential window',
    messages=('ImpactResult.exponential_window_decay_s', 'FrfSummary.exponential_window_decay_s'),
)

IMPACT: dict[str, ResultField] = _group(
    IMPACT_ID,
    TRIGGER_SAMPLE_INDEX,
    RECORD_START_SAMPLE_INDEX,
    LEVEL,
    ACCEPTED,
    FLAGS,
    IMPULSE,
    PEAK_FORCE,
    CONTACT_DURATION,
    RECORD_DURATION,
    SAMPLE_RATE,
    NATURAL_FREQUENCY,
    NATURAL_FREQUENCY_METHOD,
    NATURAL_FREQUENCY_UNCERTAINTY,
    PEAK_RECEPTANCE,
    FREQUENCY_STEP,
    FORCE_WINDOW,
    EXPONENTIAL_WINDOW_DECAY,
)
"""The scalar fields of an impact (`ImpactAnalysis`, ImpactResult.msg), by key."""

HIT_RECORD: tuple[ResultField, ...] = (
    IMPACT_ID,
    LEVEL,
    ACCEPTED,
    FLAGS,
    IMPULSE,
    PEAK_FORCE,
    CONTACT_DURATION,
    NATURAL_FREQUENCY,
    PEAK_RECEPTANCE,
)
"""A hit's record: the scalars `fmm analyze --json`, the demo and the campaign show."""

ANALYSIS_IMPACT: tuple[ResultField, ...] = (
    IMPACT_ID,
    ACCEPTED,
    FLAGS,
    IMPULSE,
    PEAK_FORCE,
    PEAK_RECEPTANCE,
    NATURAL_FREQUENCY,
    NATURAL_FREQUENCY_METHOD,
    NATURAL_FREQUENCY_UNCERTAINTY,
)
"""An impact of `fmm analyze --json` (after its file)."""

# -- the hammer alone --------------------------------------------------------------------------

HIT_TIME = ResultField('time_s', 's', 'Time of the trigger from the first sample', 'time', '.4f')
CONTACT_TIME = dataclasses.replace(CONTACT_DURATION, name='contact_time_s', messages=())
"""A hit of the force alone: how long the hammer touched (as `contact_duration_s`)."""

HAMMER_HIT: tuple[ResultField, ...] = (
    TRIGGER_SAMPLE_INDEX,
    HIT_TIME,
    PEAK_FORCE,
    IMPULSE,
    CONTACT_TIME,
    FLAGS,
    ACCEPTED,
)
"""A hit of `fmm analyze --force-only --json`: when, how hard, how long, flags, accepted."""

# -- a force level -----------------------------------------------------------------------------

LEVEL_NAME = dataclasses.replace(LEVEL, help='Name of the level', messages=('FrfSummary.level',))
NOMINAL_PEAK_FORCE = ResultField(
    'nominal_peak_force_n',
    'N',
    'Nominal peak force of the level; 0 when the level comes from clustering',
    'nominal peak force',
    fmt='g',
    messages=('FrfSummary.nominal_peak_force_n',),
)
COUNT = ResultField(
    'count',
    '-',
    'Accepted impacts averaged',
    'hits',
    fmt='d',
    messages=('FrfSummary.count',),
)
LEVEL_IMPACT_IDS = ResultField(
    'impact_ids',
    '-',
    'Their impact ids',
    'hit ids',
    fmt='',
    messages=('FrfSummary.impact_ids',),
)
MEAN_IMPULSE = dataclasses.replace(
    IMPULSE,
    name='mean_impulse_n_s',
    help="Mean impulse of the level's impacts",
    words='mean impulse',
    messages=('FrfSummary.mean_impulse_n_s',),
)
STD_IMPULSE = dataclasses.replace(
    IMPULSE,
    name='std_impulse_n_s',
    help='Sample standard deviation of the impulse; NaN for a single impact',
    words='impulse spread',
    fmt='.2g',
    messages=('FrfSummary.std_impulse_n_s',),
)
MEAN_PEAK_FORCE = dataclasses.replace(
    PEAK_FORCE,
    name='mean_peak_force_n',
    help="Mean peak force of the level's impacts",
    words='mean peak force',
    messages=('FrfSummary.mean_peak_force_n',),
)
LEVEL_PEAK_RECEPTANCE = dataclasses.replace(
    PEAK_RECEPTANCE, help='Largest |receptance| of the averaged receptance'
)
LEVEL_NATURAL_FREQUENCY = dataclasses.replace(
    NATURAL_FREQUENCY,
    help="Mean of the level's impacts' natural frequencies: of those timed by reversals, or"
    ' when none is, of their DFT peaks',
)
LEVEL_NATURAL_FREQUENCY_METHOD = dataclasses.replace(
    NATURAL_FREQUENCY_METHOD,
    help="How the impacts' f_n the level's mean takes were found: 'reversals' or 'dft_peak';"
    ' empty when none was',
)

LEVEL_FIELDS: dict[str, ResultField] = _group(
    LEVEL_NAME,
    NOMINAL_PEAK_FORCE,
    COUNT,
    LEVEL_IMPACT_IDS,
    MEAN_IMPULSE,
    STD_IMPULSE,
    MEAN_PEAK_FORCE,
    LEVEL_PEAK_RECEPTANCE,
    LEVEL_NATURAL_FREQUENCY,
    LEVEL_NATURAL_FREQUENCY_METHOD,
    dataclasses.replace(FREQUENCY_STEP, help='Frequency resolution'),
    dataclasses.replace(EXPONENTIAL_WINDOW_DECAY, help='Exponential window decay time; 0: none'),
)
"""The scalar fields of a level (`LevelSummary`, FrfSummary.msg), by key."""

LEVEL_RECORD: tuple[ResultField, ...] = (
    LEVEL_NAME,
    COUNT,
    MEAN_IMPULSE,
    STD_IMPULSE,
    MEAN_PEAK_FORCE,
    LEVEL_PEAK_RECEPTANCE,
    LEVEL_NATURAL_FREQUENCY,
)
"""A level's record: the scalars the demo's summary and the campaign's level table show."""

ANALYSIS_LEVEL: tuple[ResultField, ...] = (COUNT, MEAN_IMPULSE, LEVEL_PEAK_RECEPTANCE)
"""A level of `fmm analyze --json` (after its name)."""

DEMO_LEVEL: tuple[ResultField, ...] = (
    COUNT,
    MEAN_IMPULSE,
    STD_IMPULSE,
    LEVEL_PEAK_RECEPTANCE,
    LEVEL_NATURAL_FREQUENCY,
)
"""A level of `fmm demo`'s summary (after its name)."""

DEMO_IMPACT: tuple[ResultField, ...] = (
    IMPACT_ID,
    LEVEL,
    ACCEPTED,
    FLAGS,
    PEAK_FORCE,
    IMPULSE,
    PEAK_RECEPTANCE,
    NATURAL_FREQUENCY,
)
"""An impact of `fmm demo`'s summary."""

# -- a friction fit ------------------------------------------------------------------------------

MU = ResultField(
    'mu',
    '-',
    'Common friction coefficient of all the fitted impacts',
    'μ',
    fmt='.5f',
    messages=('FitFriction.mu', 'FrictionEstimate.mu'),
    limits=(0.0, math.inf),
)
MU_STDERR = ResultField(
    'mu_stderr',
    '-',
    'Standard error of mu',
    'σ(μ)',
    fmt='.2g',
    messages=('FitFriction.mu_stderr', 'FrictionEstimate.mu_stderr'),
)
DAMPING = ResultField(
    'damping_n_s_per_m',
    'N*s/m',
    'Viscous damping of the model, fitted or the rig constant',
    'c',
    messages=('FitFriction.damping_n_s_per_m',),
)
DAMPING_STDERR = ResultField(
    'damping_stderr_n_s_per_m',
    'N*s/m',
    'Standard error of the damping (NaN when not fitted)',
    'σ(c)',
    fmt='.2g',
    messages=('FitFriction.damping_stderr_n_s_per_m',),
)
RESIDUAL_RMS = ResultField(
    'residual_rms_m_s',
    'm/s',
    'RMS velocity residual at the common mu',
    'residual',
    fmt='.3e',
    messages=('FitFriction.residual_rms_m_s', 'FitFriction.per_impact_residual_rms_m_s'),
)
NORMALISED_RESIDUAL = ResultField(
    'normalised_residual',
    '-',
    'RMS velocity residual over the largest measured |velocity|',
    'normalised residual',
    messages=('FitFriction.residual_normalized', 'FitFriction.per_impact_residual_normalized'),
)
NOISE_STD = ResultField(
    'noise_std_m_s',
    'm/s',
    'Velocity noise estimated from the data',
    'velocity noise',
    fmt='.3e',
    messages=('FitFriction.noise_std_m_s',),
)
CONSISTENCY_CHI2 = ResultField(
    'consistency_chi2',
    '-',
    'chi^2 of the per-impact mus about the common one (NaN for one impact)',
    'χ²',
    fmt='.3g',
    messages=('FitFriction.consistency_chi2', 'FrictionEstimate.consistency_chi2'),
)
CONSISTENCY_P_VALUE = ResultField(
    'consistency_p_value',
    '-',
    'Chance of per-impact mus scattering this much if one mu served all',
    'p',
    fmt='.3g',
    messages=('FitFriction.consistency_p_value', 'FrictionEstimate.consistency_p_value'),
    limits=(0.0, 1.0),
)
IMPACT_MU = dataclasses.replace(
    MU,
    help='The impact fitted alone: its own friction coefficient',
    words='μ alone',
    messages=('FitFriction.per_impact_mu', 'FrictionEstimate.impact_mu'),
)
IMPACT_MU_STDERR = dataclasses.replace(
    MU_STDERR,
    help='Standard error of the impact fitted alone',
    messages=('FitFriction.per_impact_mu_stderr', 'FrictionEstimate.impact_mu_stderr'),
)
INITIAL_POSITION = ResultField(
    'initial_position_m',
    'm',
    "Where the impact's model started in the joint fit",
    'start',
    fmt='.3f',
    shown_unit='mm',
    shown_factor=MM_PER_M,
    messages=('FitFriction.per_impact_initial_position_m',),
)
IMPULSE_SCALE = ResultField(
    'impulse_scale',
    '-',
    "The factor the joint fit put on the impact's measured hit",
    'impulse scale',
    messages=('FitFriction.per_impact_impulse_scale',),
)
SOURCE = ResultField('file', '', 'The file, or bag@trigger, the impact came from', 'impact', 's')

FIT: dict[str, ResultField] = _group(
    MU,
    MU_STDERR,
    DAMPING,
    DAMPING_STDERR,
    RESIDUAL_RMS,
    NORMALISED_RESIDUAL,
    NOISE_STD,
    CONSISTENCY_CHI2,
    CONSISTENCY_P_VALUE,
)
"""The scalar fields of a friction fit (`FrictionResult`, FitFriction.srv), by key."""

FIT_IMPACT: tuple[ResultField, ...] = (
    IMPACT_ID,
    SOURCE,
    IMPACT_MU,
    IMPULSE,
    RESIDUAL_RMS,
    IMPACT_MU_STDERR,
    NORMALISED_RESIDUAL,
    INITIAL_POSITION,
    IMPULSE_SCALE,
)
"""An impact of a fit (`FrictionResult.per_impact`, `fmm fit --json`'s per_file), in order."""

# -- a diagnosis ---------------------------------------------------------------------------------

DIAGNOSIS: dict[str, ResultField] = _group(
    ResultField(
        'missing_effect',
        '',
        "The effect the diagnosis names ('none': the model explains the data)",
        'missing effect',
        's',
        messages=('DiagnoseModel.missing_effect',),
    ),
    ResultField('verdict', '', 'How sure the diagnosis is of its answer', 'verdict', 's'),
    dataclasses.replace(MU, help='mu of the base model fitted to the data', messages=()),
    dataclasses.replace(MU_STDERR, messages=()),
    dataclasses.replace(NOISE_STD, messages=()),
    ResultField(
        'residual_noise_std_m_s',
        'm/s',
        'Velocity noise where the rig rests, which the gaps are beyond',
        'rest noise',
        '.3g',
    ),
    ResultField('force_noise_std_n', 'N', 'Force noise of the hits at rest', 'force noise', '.3g'),
    ResultField(
        'required_score',
        '-',
        'The score an effect must reach to be named',
        'required score',
        '.3g',
    ),
    ResultField(
        'parameter_at_bound',
        '',
        'Whether a fitted parameter ended on a bound of its fitting range (a limit, not an '
        'estimate), by parameter name',
        'at its bound',
        messages=(
            'DiagnoseModel.parameter_at_bound',
            'DiagnoseModel.missing_effect_parameter_at_bound',
        ),
    ),
    ResultField(
        'unobservable',
        '',
        "A candidate's 'these records cannot show ...' and what would, when its detection "
        'limit lies outside its physical range; empty when the records can show it',
        'unobservable',
        's',
        messages=('DiagnoseModel.candidate_unobservable',),
    ),
)
"""The fields of a diagnosis (`Diagnosis`, DiagnoseModel.srv), by key: its scalars, and the
flags its parameters and candidates carry."""
