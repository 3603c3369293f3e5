"""From impact records to per-impact results, per-level averaged FRFs and the linearity law.

This is the pipeline the analyzer node, `fmm analyze` and the fitter share: `analyze_impact`
turns one `ImpactRecord` into an `ImpactAnalysis` (flags, impulse, peak force, contact duration,
band-limited mobility and receptance), and `summarize` groups results into force levels,
averages each level (the paper's plain mean, H1, H2, coherence) and fits peak |receptance|
against impulse (the paper's Fig. 17). `select_impacts` is the one rule every fit and
diagnosis (CLI, workflows, fitter node) takes its impacts by: the flagged ones are left out
and named, unless asked for. `ImpactAnalysis` and `LevelSummary` carry the fields of
`fmm_interfaces/ImpactResult.msg` and `FrfSummary.msg` under the same names (complex arrays
split into `_real`/`_imag` there), so the ROS shell converts them field by field.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from fmm_ros.core import results_schema as schema
from fmm_ros.core.settings import result_field, setting
from fmm_ros.core.signal import frf, pulse, response
from fmm_ros.core.signal.capture import (
    contact_start_index,
    resting_force_level,
    with_trigger,
)
from fmm_ros.core.signal.config import (  # noqa: F401 (re-exported: declared in config)
    DEFAULT_ANALYSIS,
    DEFAULT_CAPTURE,
    FLAGS,
    UNDETERMINED,
    AnalysisConfig,
    CaptureConfig,
    NominalLevel,
    paper_levels,
)
from fmm_ros.core.signal.judging import Decision, is_taken
from fmm_ros.core.signal.levels import assign_nominal_levels, cluster_levels
from fmm_ros.core.signal.quality import quality_flags
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.errors import BadInputError, SelectionError


@dataclass(frozen=True, eq=False)
class ImpactAnalysis:
    """One impact analysed: the fields of ImpactResult.msg plus the spectra averaging needs."""

    impact_id: int = schema.IMPACT_ID.field()
    trigger_sample_index: int = schema.TRIGGER_SAMPLE_INDEX.field()
    record_start_sample_index: int = schema.RECORD_START_SAMPLE_INDEX.field()
    level: str = schema.LEVEL.field()
    accepted: bool = schema.ACCEPTED.field()
    flags: tuple[str, ...] = schema.FLAGS.field()
    impulse_n_s: float = schema.IMPULSE.field()
    peak_force_n: float = schema.PEAK_FORCE.field()
    contact_duration_s: float = schema.CONTACT_DURATION.field()
    record_duration_s: float = schema.RECORD_DURATION.field()
    sample_rate_hz: float = schema.SAMPLE_RATE.field()
    natural_frequency_hz: float = schema.NATURAL_FREQUENCY.field()
    natural_frequency_method: str = schema.NATURAL_FREQUENCY_METHOD.field()
    natural_frequency_uncertainty_hz: float = schema.NATURAL_FREQUENCY_UNCERTAINTY.field()
    peak_receptance_m_per_n: float = schema.PEAK_RECEPTANCE.field()
    frequency_step_hz: float = schema.FREQUENCY_STEP.field()
    frequency_hz: np.ndarray = result_field(unit='Hz', help='Band-limited frequency axis')
    mobility: np.ndarray = result_field(unit='m/(N*s)', help='Mobility V/F (complex)')
    receptance: np.ndarray = result_field(unit='m/N', help='Receptance X/F (complex)')
    force_window_s: float = schema.FORCE_WINDOW.field()
    exponential_window_decay_s: float = schema.EXPONENTIAL_WINDOW_DECAY.field()
    force_spectrum: np.ndarray = result_field(
        unit='N', help='Unscaled DFT of the (windowed) force, band-limited, for H1/H2/coherence'
    )
    velocity_spectrum: np.ndarray = result_field(
        unit='m/s', help='Unscaled DFT of the (windowed) velocity, band-limited'
    )
    excitation_spectrum: np.ndarray = result_field(
        unit='N',
        help='Unscaled DFT of the hammer pulse alone, baseline removed, band-limited: the '
        'excitation the usable band is judged by',
    )
    source: str = setting('', help='The file, or bag@trigger, the record came from')

    @property
    def accelerance(self) -> np.ndarray:
        """Accelerance A/F [m/(N*s^2)] = i*omega * mobility."""
        return frf.accelerance_from_mobility(self.mobility, self.frequency_hz)


@dataclass(frozen=True, eq=False)
class LevelSummary:
    """One force level's averaged FRF: the per-level fields of FrfSummary.msg."""

    level: str = schema.LEVEL_FIELDS['level'].field()
    nominal_peak_force_n: float = schema.NOMINAL_PEAK_FORCE.field()
    count: int = schema.COUNT.field()
    impact_ids: tuple[int, ...] = schema.LEVEL_IMPACT_IDS.field()
    mean_impulse_n_s: float = schema.MEAN_IMPULSE.field()
    std_impulse_n_s: float = schema.STD_IMPULSE.field()
    mean_peak_force_n: float = schema.MEAN_PEAK_FORCE.field()
    peak_receptance_m_per_n: float = schema.LEVEL_PEAK_RECEPTANCE.field()
    natural_frequency_hz: float = schema.LEVEL_NATURAL_FREQUENCY.field()
    natural_frequency_method: str = schema.LEVEL_NATURAL_FREQUENCY_METHOD.field()
    frequency_step_hz: float = schema.LEVEL_FIELDS['frequency_step_hz'].field()
    frequency_hz: np.ndarray = result_field(unit='Hz', help='Band-limited frequency axis')
    mobility: np.ndarray = result_field(
        unit='m/(N*s)', help="Plain mean of the trials' mobility (the paper's average)"
    )
    receptance: np.ndarray = result_field(unit='m/N', help="Plain mean of the trials' receptance")
    h1_mobility: np.ndarray = result_field(unit='m/(N*s)', help='H1 estimate of the mobility')
    h2_mobility: np.ndarray = result_field(unit='m/(N*s)', help='H2 estimate of the mobility')
    coherence: np.ndarray = result_field(help='Ordinary coherence of force and velocity [-]')
    exponential_window_decay_s: float = schema.LEVEL_FIELDS['exponential_window_decay_s'].field()


@dataclass(frozen=True, eq=False)
class Summary:
    """Every impact with its level and verdict, each level's average, and the linearity fit."""

    impacts: tuple[ImpactAnalysis, ...]
    levels: tuple[LevelSummary, ...]
    # Peak |receptance| [m/N] against mean impulse [N*s] over the levels.
    linearity: frf.LinearFit


def _windowed(
    force: np.ndarray,
    measured: np.ndarray,
    rate: float,
    trigger: int,
    contact_start: int,
    analysis: AnalysisConfig,
) -> tuple[np.ndarray, np.ndarray]:
    """The force and response the DFT sees: the analysis's force and exponential windows on.

    The force window is laid on the force less its pre-contact mean; the exponential window
    on both channels, from the trigger.
    """
    if analysis.force_window_s is not None:
        offset = float(np.mean(force[:contact_start])) if contact_start else 0.0
        force = (force - offset) * frf.force_window(
            force.size,
            rate,
            start_index=trigger,
            width_s=analysis.force_window_s,
            taper_s=analysis.force_window_taper_s,
        )
    if analysis.exponential_decay_s is not None:
        weight = frf.exponential_window(
            force.size, rate, decay_time_s=analysis.exponential_decay_s, start_index=trigger
        )
        force, measured = force * weight, measured * weight
    return force, measured


def _band_spectra(
    record: ImpactRecord,
    raw_force: np.ndarray,
    force: np.ndarray,
    velocity: np.ndarray,
    contact_start: int,
    capture: CaptureConfig,
    analysis: AnalysisConfig,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Frequency [Hz], force, velocity and excitation spectra of a hit, up to the band limit.

    force and velocity: the windowed records, DFT'd zero-padded to `record.window_samples`;
    the measured response is turned into velocity bin by bin; the excitation is the spectrum
    of the triggering pulse alone (raw_force, baseline removed).
    """
    n_fft, rate = record.window_samples, record.sample_rate_hz
    bins = frf.band_bins(n_fft, rate, analysis.band_limit_hz)
    force_spectrum, velocity_spectrum = frf.spectra(force, velocity, n_fft)
    # Copies, so the full-length spectra are freed rather than kept alive by the slices.
    force_spectrum = force_spectrum[:bins].copy()
    frequency = frf.frequency_axis(n_fft, rate, bins)
    velocity_spectrum = response.convert_spectrum(
        velocity_spectrum[:bins], frequency, record.response_quantity, response.VELOCITY
    ).copy()
    excitation_spectrum = frf.pulse_spectrum(
        raw_force, capture.rearm_level_n, n_fft, contact_start
    )[:bins].copy()
    return frequency, force_spectrum, velocity_spectrum, excitation_spectrum


def analyze_impact(
    record: ImpactRecord,
    capture: CaptureConfig = DEFAULT_CAPTURE,
    analysis: AnalysisConfig = DEFAULT_ANALYSIS,
    *,
    impact_id: int = 0,
) -> ImpactAnalysis:
    """Flags, impulse, peak force, contact duration and FRFs of one impact record.

    The DFT runs over the whole record zero-padded to `record.window_samples` (the paper's
    method). The impulse is the trapezoid over the pulse that fired the trigger, baseline
    removed (`frf.pulse_impulse`): the physical impulse, whatever the windows or the noise of
    the rest of the record. f_n is timed by the velocity reversals, or read at the DFT peak of
    a ring too short for them, with its uncertainty (`frf.natural_frequency_of_hit`); a record
    with neither is `undetermined`. The level is assigned later by `summarize`.
    """
    record = with_trigger(record, capture)
    flags = quality_flags(record, capture)
    rate = record.sample_rate_hz
    trigger = record.trigger_offset
    raw_force = record.force_n - resting_force_level(record.force_n, trigger, capture)
    contact_start = contact_start_index(raw_force, trigger, capture)
    interval = frf.contact_interval(raw_force, capture.rearm_level_n, contact_start)
    peak_force = float(np.max(raw_force[interval[0] : interval[1]])) if interval else float('nan')

    impulse = frf.pulse_impulse(raw_force, rate, capture.rearm_level_n, contact_start)
    # The DFT of what the sensor measured, turned into velocity bin by bin (exact).
    force, velocity = _windowed(
        raw_force, record.measured[0], rate, trigger, contact_start, analysis
    )

    n_fft = record.window_samples
    frequency, force_spectrum, velocity_spectrum, excitation_spectrum = _band_spectra(
        record, raw_force, force, velocity, contact_start, capture, analysis
    )
    mobility = frf.mobility(force_spectrum, velocity_spectrum)
    receptance = frf.receptance_from_mobility(mobility, frequency)
    peak_band = _peak_band(excitation_spectrum, frequency, analysis)
    peak_receptance, _ = frf.peak_magnitude(receptance, frequency, peak_band)
    natural = frf.natural_frequency_of_hit(
        record.velocity_m_s, rate, velocity_spectrum, excitation_spectrum, frequency, peak_band
    )
    determined = _determined(impulse, natural.value_hz, peak_receptance)
    if not determined and not flags:
        flags = (UNDETERMINED,)
    return ImpactAnalysis(
        impact_id=impact_id,
        trigger_sample_index=record.trigger_sample_index,
        record_start_sample_index=record.record_start_sample_index,
        level='',
        accepted=determined and not set(flags) & set(analysis.reject_flags),
        flags=flags,
        impulse_n_s=impulse,
        peak_force_n=peak_force,
        contact_duration_s=frf.contact_duration(
            raw_force, rate, capture.rearm_level_n, contact_start
        ),
        record_duration_s=n_fft / rate,
        sample_rate_hz=rate,
        natural_frequency_hz=natural.value_hz,
        natural_frequency_method=natural.method,
        natural_frequency_uncertainty_hz=natural.uncertainty_hz,
        peak_receptance_m_per_n=peak_receptance,
        frequency_step_hz=rate / n_fft,
        frequency_hz=frequency,
        mobility=mobility,
        receptance=receptance,
        force_window_s=analysis.force_window_s or 0.0,
        exponential_window_decay_s=analysis.exponential_decay_s or 0.0,
        force_spectrum=force_spectrum,
        velocity_spectrum=velocity_spectrum,
        excitation_spectrum=excitation_spectrum,
        source=record.source,
    )


def summarize(
    results: Sequence[ImpactAnalysis],
    analysis: AnalysisConfig = DEFAULT_ANALYSIS,
    decisions: Mapping[int, Decision] | None = None,
) -> Summary:
    """Assign levels, judge every impact, average each level and fit |receptance| vs impulse.

    With nominal levels an impact belongs to the nearest one within its tolerance, or to none
    (flag `out_of_tolerance`); without, peak forces are clustered into `level_1`, `level_2`, ...
    in ascending force. Impacts that share the session's top force to the last bit, several
    of them, are `clipped` (`pulse.shared_top`: a one-sample clipped top is no plateau). Only
    accepted impacts enter the averages, or under decisions (impact id -> the newest
    `Decision`) the ones a fit takes (`judging.is_taken`, as `select_impacts`); every impact
    is returned, `accepted` its flags' verdict.
    """
    peaks = np.array([result.peak_force_n for result in results], dtype=float)
    if analysis.levels:
        index = assign_nominal_levels(
            peaks,
            [level.peak_force_n for level in analysis.levels],
            [level.tolerance_n for level in analysis.levels],
        )
        names = [analysis.levels[i].name if i >= 0 else '' for i in index]
        level_order = [(level.name, level.peak_force_n) for level in analysis.levels]
    else:
        labels = cluster_levels(peaks, analysis.cluster_relative_gap)
        names = [f'level_{label + 1}' if label >= 0 else '' for label in labels]
        level_order = [(f'level_{label + 1}', 0.0) for label in range(labels.max(initial=-1) + 1)]

    judged = []
    on_top = pulse.shared_top(peaks)  # clipped hits: several share the top to the last bit
    for result, name, topped in zip(results, names, on_top, strict=True):
        flags = set(result.flags) - {'out_of_tolerance'}
        if analysis.levels and not name:
            flags.add('out_of_tolerance')
        if topped:
            flags.add('clipped')
        ordered = tuple(flag for flag in FLAGS if flag in flags)
        accepted = not flags & set(analysis.reject_flags) and _determined(
            result.impulse_n_s, result.natural_frequency_hz, result.peak_receptance_m_per_n
        )
        judged.append(dataclasses.replace(result, level=name, flags=ordered, accepted=accepted))

    levels = []
    for name, nominal in level_order:
        members = [
            result
            for result in judged
            if result.level == name and is_taken(result.impact_id, result.accepted, decisions or {})
        ]
        if members:
            levels.append(_level_summary(name, nominal, members, analysis))
    linearity = frf.linear_fit(
        [level.mean_impulse_n_s for level in levels],
        [level.peak_receptance_m_per_n for level in levels],
    )
    return Summary(impacts=tuple(judged), levels=tuple(levels), linearity=linearity)


def _level_summary(
    name: str, nominal_peak_force_n: float, members: list[ImpactAnalysis], analysis: AnalysisConfig
) -> LevelSummary:
    """Average one level's accepted impacts (which must share one frequency grid)."""
    first = members[0]
    for result in members[1:]:
        if result.frequency_hz.size != first.frequency_hz.size or not np.isclose(
            result.frequency_step_hz, first.frequency_step_hz, rtol=1e-9
        ):
            raise BadInputError(
                f'level {name}: impacts {first.impact_id} and {result.impact_id} have different '
                f'frequency grids ({first.frequency_step_hz:.6g} Hz x {first.frequency_hz.size} vs '
                f'{result.frequency_step_hz:.6g} Hz x {result.frequency_hz.size}); records must '
                'share sample rate and window length to be averaged'
            )
    average = frf.average_frf(
        np.stack([result.force_spectrum for result in members]),
        np.stack([result.velocity_spectrum for result in members]),
    )
    receptance = frf.receptance_from_mobility(average.mean_mobility, first.frequency_hz)
    peak, _ = frf.peak_magnitude(
        receptance,
        first.frequency_hz,
        _peak_band(
            np.stack([result.excitation_spectrum for result in members]),
            first.frequency_hz,
            analysis,
        ),
    )
    natural_frequency, natural_method = _level_natural_frequency(members)
    impulses = np.array([result.impulse_n_s for result in members])
    return LevelSummary(
        level=name,
        nominal_peak_force_n=nominal_peak_force_n,
        count=len(members),
        impact_ids=tuple(result.impact_id for result in members),
        mean_impulse_n_s=float(impulses.mean()),
        std_impulse_n_s=float(impulses.std(ddof=1)) if impulses.size > 1 else float('nan'),
        mean_peak_force_n=float(np.mean([result.peak_force_n for result in members])),
        peak_receptance_m_per_n=peak,
        natural_frequency_hz=natural_frequency,
        natural_frequency_method=natural_method,
        frequency_step_hz=first.frequency_step_hz,
        frequency_hz=first.frequency_hz,
        mobility=average.mean_mobility,
        receptance=receptance,
        h1_mobility=average.h1_mobility,
        h2_mobility=average.h2_mobility,
        coherence=average.coherence,
        exponential_window_decay_s=first.exponential_window_decay_s,
    )


def _level_natural_frequency(members: Sequence[ImpactAnalysis]) -> tuple[float, str]:
    """A level's f_n [Hz] and its method: the mean of its reversal-timed hits', else of the rest.

    A short ring's DFT peak lies above f_n by up to its stated uncertainty (a few %), the
    reversals' period within 1e-4: a level that has both takes the reversals alone.
    """
    for method in (frf.REVERSALS, frf.DFT_PEAK):
        frequencies = [
            m.natural_frequency_hz
            for m in members
            if m.natural_frequency_method == method and np.isfinite(m.natural_frequency_hz)
        ]
        if frequencies:
            return float(np.mean(frequencies)), method
    return float('nan'), ''


def _determined(impulse_n_s: float, natural_frequency_hz: float, peak_receptance: float) -> bool:
    """Whether a hit's headline numbers are all finite: no hit is accepted without them.

    A NaN comes from a record flagged already (a gap, a NaN sample), or else is flagged
    `undetermined`; either way the hit never enters an average or a fit.
    """
    return bool(np.isfinite((impulse_n_s, natural_frequency_hz, peak_receptance)).all())


def _peak_band(
    excitation_spectrum: np.ndarray, frequency_hz: np.ndarray, analysis: AnalysisConfig
) -> tuple[float, float]:
    """The configured peak band, its top lowered to where the pulse's excitation runs out.

    A band limit above the configured top (a structure's kHz modes, not the FMM's 2.2 Hz)
    raises the top to it: the band then follows the data, up to what the hammer excited.
    """
    low, high = analysis.peak_band_hz
    if analysis.band_limit_hz is None or analysis.band_limit_hz > high:
        high = analysis.band_limit_hz or frequency_hz[-1]
    usable = frf.excitation_bandwidth(
        excitation_spectrum, frequency_hz, analysis.excitation_drop_db
    )
    return low, high if np.isnan(usable) else min(high, usable)


class JudgedImpact(Protocol):
    """What selection needs of an impact: an `ImpactAnalysis`, or the fitter's held impact."""

    impact_id: int
    accepted: bool
    flags: tuple[str, ...]


@dataclass(frozen=True)
class ImpactSelection:
    """The impacts a fit takes and those it leaves out, each with its flags and source."""

    chosen: tuple[int, ...]
    # (impact id, flags, source) of every impact left out, in the order given.
    excluded: tuple[tuple[int, tuple[str, ...], str], ...]
    # (impact id, flags, source) of flagged impacts taken because include_flagged was set.
    included_flagged: tuple[tuple[int, tuple[str, ...], str], ...] = ()
    # Decisions that overruled the flags (`core.signal.judging`), in the order given.
    judged: tuple[Decision, ...] = ()

    @property
    def chain_refusal(self) -> str:
        """Why chained starts cannot take these impacts ('' when they can).

        A chain holds over every hit of one continuous session: a hit left out moved the rig
        between two records that are taken (`FitSpec.chain_starts`).
        """
        if not self.excluded:
            return ''
        return (
            f'chained starts need every hit of the session, in order: {len(self.excluded)} '
            f'flagged impact(s) were left out ({_named(self.excluded)}); take them '
            '(--include-flagged) or do not chain the starts'
        )

    def chained(self, chain_starts: bool) -> bool:
        """Whether these impacts are fitted with chained starts; BadInputError if they cannot be.

        The one check every boundary (CLI, fitter node, session workflow) makes before a
        chained fit or diagnosis: `chain_refusal` names what breaks the chain.
        """
        if chain_starts and self.chain_refusal:
            raise BadInputError(self.chain_refusal)
        return chain_starts

    @property
    def note(self) -> str:
        """One line naming what was left out or taken despite its flags ('' when neither)."""
        parts = []
        if self.excluded:
            parts.append(
                f'left out {len(self.excluded)} flagged impact(s): {_named(self.excluded)} '
                '(--include-flagged takes them)'
            )
        if self.included_flagged:
            parts.append(
                f'WARNING: {len(self.included_flagged)} flagged impact(s) included on '
                f'request: {_named(self.included_flagged)}'
            )
        if self.judged:
            parts.append(
                f'{len(self.judged)} judged: '
                + ', '.join(decision.describe() for decision in self.judged)
            )
        return '; '.join(parts)


def select_impacts(
    impacts: Summary | Iterable[JudgedImpact],
    *,
    include_flagged: bool = False,
    min_clean: int = 1,
    decisions: Mapping[int, Decision] | None = None,
) -> ImpactSelection:
    """The impacts a fit or diagnosis takes: the accepted ones, or all with include_flagged.

    An impact is left out when its flags rejected it (`AnalysisConfig.reject_flags`, every flag
    by default; the analyzer node's `reject_flags` for its messages): a clipped force, a double
    hit, a dead vibrometer or a gap gives a confident wrong mu, so it never enters a fit
    silently. include_flagged takes every impact (and the selection says which were flagged).
    decisions (impact id -> the newest `Decision` about it) overrule the flags and
    include_flagged: an operator's or judge function's accept takes an impact, a reject or
    pending leaves it out, and the selection lists them (`judged`).
    Raises SelectionError naming the impacts left out and their flags when fewer than
    min_clean remain.
    """
    if isinstance(impacts, Summary):
        impacts = impacts.impacts
    decisions = decisions or {}
    chosen, excluded, included, judged = [], [], [], []
    for impact in impacts:
        entry = (int(impact.impact_id), tuple(impact.flags), getattr(impact, 'source', ''))
        decision = decisions.get(entry[0])
        if decision is not None and decision.taken is not None:
            judged.append(decision)
            if decision.taken:
                chosen.append(entry[0])
        elif impact.accepted:
            chosen.append(entry[0])
        elif include_flagged:
            chosen.append(entry[0])
            included.append(entry)
        else:
            excluded.append(entry)
    selection = ImpactSelection(tuple(chosen), tuple(excluded), tuple(included), tuple(judged))
    if len(chosen) < min_clean:
        total = len(chosen) + len(excluded) + len(judged)
        if total == 0:
            raise SelectionError('no impact to fit', selection)
        count = (
            'no clean impact to fit'
            if not chosen
            else f'{len(chosen)} clean impact(s) of {total}, {min_clean} needed'
        )
        left_out = [f'{_named(excluded)} flagged (--include-flagged takes them anyway)'] * bool(
            excluded
        ) + [decision.describe() for decision in judged if not decision.taken]
        raise SelectionError(f'{count}: {"; ".join(left_out)}', selection)
    return selection


def _named(entries: Sequence[tuple[int, tuple[str, ...], str]]) -> str:
    """'impact 3 (hit3.csv: double_hit), impact 5 (clipped, no_response)'."""
    return ', '.join(
        f'impact {impact_id} ({f"{source}: " if source else ""}{", ".join(flags) or "rejected"})'
        for impact_id, flags, source in entries
    )
