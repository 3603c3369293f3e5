"""Figures of one impact session, in the style of the paper's Figs. 12-24.

Each function takes analysed data (records, `ImpactAnalysis` and `LevelSummary` objects) and
returns a `matplotlib.figure.Figure`; nothing is computed here that the signal core already
computes.
Time is counted from each hit's trigger, so trials overlay; frequency axes stop where the
figure's subject does (a few f_n for the resonance, 20 Hz for the odd harmonics).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure

from fmm_ros.constants import MM_PER_M, MOBILITY_DISPLAY_UNIT, RECEPTANCE_DISPLAY_UNIT
from fmm_ros.core import results_schema as schema
from fmm_ros.core.results_schema import format_with_uncertainty
from fmm_ros.core.signal import frf
from fmm_ros.core.signal.analysis import ImpactAnalysis, LevelSummary, NominalLevel, Summary
from fmm_ros.core.signal.capture import DEFAULT_CAPTURE, CaptureConfig
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.errors import BadInputError
from fmm_ros.report.plotting import (
    FREQUENCY_LABEL,
    MEAN_COLOUR,
    MODEL_COLOUR,
    MS_PER_S,
    REJECTED_COLOUR,
    figure_title,
    level_colour,
    new_figure,
    odd_harmonics,
    plot_trace,
    thaw_ticks,
)
from fmm_ros.workflows.model import decay_end_s, trigger_offset

# The force zoom shows this long before the contact and after the last pulse [s].
FORCE_MARGIN_S = 1e-3
# How far past f_n the resonance figures (Figs. 14-16, 19/21/23) run.
RESONANCE_SPAN = 2.5
# The paper's Fig. 24 runs to 20 Hz.
HARMONICS_TOP_HZ = 20.0
VELOCITY_LABEL = 'velocity [mm/s]'


class HitFigures:
    """The figure of each hit (Figs. 18/20/22), drawn hit after hit into one reused Figure.

    A report has one such figure per hit. Making a Figure, its axes and their ticks anew
    for each costs more than drawing it (and the text measured for one figure's renderer
    is measured again for the next), so the report keeps one Figure per layout (with and
    without the model's residual row) and replaces data, limits and titles. A figure
    `draw` returns is valid until the next `draw` of the same layout.
    """

    def __init__(self) -> None:
        self._panels: dict[bool, _HitPanels] = {}

    def draw(
        self,
        record: ImpactRecord,
        result: ImpactAnalysis,
        *,
        capture: CaptureConfig = DEFAULT_CAPTURE,
        model_velocity_m_s: np.ndarray | None = None,
        model_label: str = '',
        colour: str = 'tab:blue',
    ) -> Figure:
        """One hit: force pulse zoomed, the whole decay, model and residual.

        Top: the force around the contact (widened to show a second pulse of a double hit).
        Middle: measured velocity until the rig is at rest, with the model's velocity over
        it when given. Bottom (with a model): measured minus model, where they disagree.
        """
        with_model = model_velocity_m_s is not None
        if with_model not in self._panels:
            self._panels[with_model] = _HitPanels(with_model)
        panels = self._panels[with_model]
        figure, axes = panels.figure, panels.axes
        thaw_ticks(figure)
        for ax, start in zip(axes, panels.start, strict=True):
            ax.set_position(start)  # so its ticks are chosen as in a fresh figure
        verdict = 'accepted' if result.accepted else 'rejected: ' + ', '.join(result.flags)
        figure_title(
            figure,
            ' · '.join(
                part
                for part in (
                    f'hit {result.impact_id}',
                    source_name(result.source),
                    f'level: {result.level}' if result.level else 'no level',
                    verdict,
                )
                if part
            ),
        )
        trigger = trigger_offset(result)
        rate = record.sample_rate_hz
        start_s, end_s = _force_window([record], [trigger], capture)
        panels.force.set_trace(*_force_trace(record, trigger, start_s, end_s))
        panels.force.set_color(colour)
        axes[0].set_xlim(start_s * MS_PER_S, end_s * MS_PER_S)
        axes[0].set_title(
            f'peak {result.peak_force_n:.4g} N, impulse '
            f'{result.impulse_n_s:.4g} N·s, contact '
            f'{result.contact_duration_s * MS_PER_S:.3g} ms',
            fontsize='small',
        )
        velocities = [record.velocity_m_s] + ([model_velocity_m_s] if with_model else [])
        end_s = decay_end_s(velocities, trigger, rate, capture.rest_velocity_m_s)
        time_s, shown = _decay_span(record, trigger, end_s)
        panels.measured.set_trace(time_s, record.velocity_m_s[shown] * MM_PER_M)
        panels.measured.set_color(colour)
        if with_model:
            model = model_velocity_m_s[shown] * MM_PER_M
            panels.model.set_trace(time_s, model)
            panels.model.set_label(model_label or 'model')
            panels.residual.set_trace(time_s, record.velocity_m_s[shown] * MM_PER_M - model)
            axes[1].legend(loc='upper right', fontsize='small')
        for ax in axes[1:]:
            ax.set_xlim(time_s[0], end_s)
        for ax in axes:
            ax.relim()
            ax.autoscale_view(scalex=False)
        return figure


class _HitPanels:
    """One layout of the hit figure: its Figure, axes and the lines `HitFigures` refills."""

    def __init__(self, with_model: bool) -> None:
        # A title, so the starting margins leave room for one (each draw sets its own).
        self.figure, self.axes = new_figure(3 if with_model else 2, 1, title='hit')
        self.force = plot_trace(self.axes[0], [], [], linewidth=0.8)
        _force_labels(self.axes[0])
        self.measured = plot_trace(self.axes[1], [], [], linewidth=0.8, label='measured')
        if with_model:
            self.model = plot_trace(
                self.axes[1], [], [], color=MODEL_COLOUR, linewidth=0.8, linestyle='--'
            )
            self.residual = plot_trace(self.axes[2], [], [], color='tab:purple', linewidth=0.6)
            self.axes[2].set_ylabel('measured − model\n[mm/s]')
        self.axes[1].set_ylabel(VELOCITY_LABEL)
        self.axes[-1].set_xlabel('time from trigger [s]')
        self.start = [ax.get_position() for ax in self.axes]


def level_trials_figure(
    level: str,
    records: Sequence[ImpactRecord],
    results: Sequence[ImpactAnalysis],
    *,
    colour: str = 'tab:blue',
    capture: CaptureConfig = DEFAULT_CAPTURE,
) -> Figure:
    """Every trial of one level overlaid (Fig. 12): force pulses, then velocity decays."""
    figure, axes = new_figure(
        2, 1, title=f'level {level}: {len(records)} trial(s), aligned at the trigger'
    )
    triggers = [trigger_offset(result) for result in results]
    _force_zoom(axes[0], records, triggers, [colour] * len(records), capture)
    rate = records[0].sample_rate_hz
    end_s = decay_end_s(
        [record.velocity_m_s for record in records], triggers, rate, capture.rest_velocity_m_s
    )
    for record, trigger in zip(records, triggers, strict=True):
        time_s, shown = _decay_span(record, trigger, end_s)
        plot_trace(
            axes[1],
            time_s,
            record.velocity_m_s[shown] * MM_PER_M,
            color=colour,
            linewidth=0.6,
            alpha=0.7,
        )
    axes[1].set_xlim(right=end_s)
    axes[1].set_ylabel(VELOCITY_LABEL)
    axes[1].set_xlabel('time from trigger [s]')
    return figure


def frf_trials_figure(
    level: LevelSummary,
    trials: Sequence[ImpactAnalysis],
    quantity: str,
    *,
    colour: str = 'tab:blue',
    top_hz: float | None = None,
) -> Figure:
    """One level's trials and their mean (Figs. 14, 15): real/imaginary and magnitude/phase.

    Real and imaginary parts on the left (the paper's view), magnitude on a log axis and phase
    on the right (a Bode plot: the decades away from resonance, where the odd harmonics and the
    noise floor sit, stay readable). quantity: 'mobility' or 'receptance'; the mean is the
    level's plain frequency-domain average (the paper's).
    """
    unit = _frf_unit(quantity)
    top_hz = top_hz or resonance_top_hz(level.natural_frequency_hz)
    figure, axes = new_figure(
        2,
        2,
        sharex=True,
        title=f'{quantity}, level {level.level}: {len(trials)} trial(s) and their mean',
    )
    band = level.frequency_hz <= top_hz
    frequency = level.frequency_hz[band]
    views = (
        (axes[0], lambda h: np.real(h) * MM_PER_M, f'real [{unit}]'),
        (axes[2], lambda h: np.imag(h) * MM_PER_M, f'imaginary [{unit}]'),
        (axes[1], lambda h: np.abs(h) * MM_PER_M, f'magnitude [{unit}], log'),
        (axes[3], lambda h: np.angle(h, deg=True), 'phase [°]'),
    )
    for ax, view, label in views:
        for number, trial in enumerate(trials):
            ax.plot(
                frequency,
                view(getattr(trial, quantity)[band]),
                color=colour,
                linewidth=0.6,
                alpha=0.6,
                label='trials' if number == 0 else None,
            )
        ax.plot(frequency, view(getattr(level, quantity)[band]), color=MEAN_COLOUR, linewidth=1.4)
        ax.lines[-1].set_label('mean')
        ax.set_ylabel(label)
    axes[1].set_yscale('log')
    axes[3].set_yticks([-180, -90, 0, 90, 180])
    axes[0].legend(loc='upper right', fontsize='small')
    for ax in axes[2:]:
        ax.set_xlabel(FREQUENCY_LABEL)
    axes[2].set_xlim(0, top_hz)
    return figure


def coherence_figure(
    level: LevelSummary,
    trials: Sequence[ImpactAnalysis],
    *,
    colour: str = 'tab:blue',
    top_hz: float | None = None,
) -> Figure:
    """How well one level's hits agree: their coherence, and the spread of their mobility.

    Top: the ordinary coherence of force and velocity over the level's trials (1 where every
    hit saw the same linear FRF; friction, noise and leakage lower it). It needs two hits: of
    one hit it is 1 at every frequency by definition, so the panel says so instead of drawing
    a flat 1 that would read as a perfect measurement. Bottom: |mobility| of
    the mean, with the band from the smallest to the largest of the hits at each frequency.
    """
    top_hz = top_hz or resonance_top_hz(level.natural_frequency_hz)
    figure, axes = new_figure(
        2,
        1,
        sharex=True,
        title=f'coherence and spread, level {level.level}: {len(trials)} trial(s)',
    )
    band = level.frequency_hz <= top_hz
    frequency = level.frequency_hz[band]
    if len(trials) >= 2:
        axes[0].plot(frequency, level.coherence[band], color=colour, linewidth=1.2, label='γ²')
    else:
        axes[0].set_title(
            f'coherence needs two hits: level {level.level} has one', fontsize='small'
        )
        axes[0].text(
            0.5,
            0.5,
            'not drawn: of a single hit it is 1 at every frequency, whatever the data',
            transform=axes[0].transAxes,
            ha='center',
            va='center',
            fontsize='small',
        )
    axes[0].set_ylim(-0.05, 1.05)
    axes[0].set_ylabel('coherence γ² [-]')
    magnitudes = np.abs([trial.mobility[band] for trial in trials]) * MM_PER_M
    axes[1].fill_between(
        frequency,
        magnitudes.min(axis=0),
        magnitudes.max(axis=0),
        color=colour,
        alpha=0.3,
        linewidth=0,
        label=f'hits (min to max of {len(trials)})',
    )
    axes[1].plot(
        frequency,
        np.abs(level.mobility[band]) * MM_PER_M,
        color=MEAN_COLOUR,
        linewidth=1.2,
        label='mean',
    )
    axes[1].set_ylabel(f'|mobility| [{MOBILITY_DISPLAY_UNIT}]')
    axes[1].legend(loc='upper right', fontsize='small')
    axes[1].set_xlabel(FREQUENCY_LABEL)
    axes[1].set_xlim(0, top_hz)
    return figure


def level_magnitude_figure(
    levels: Sequence[LevelSummary], *, top_hz: float | None = None
) -> Figure:
    """Mean |receptance| of every level (Fig. 16): it grows with the force.

    Left on a linear axis, as the paper draws it; right the same on a log axis, where the
    levels' responses away from resonance (harmonics, noise floor) can be told apart.
    """
    top_hz = top_hz or resonance_top_hz(np.nanmax([lv.natural_frequency_hz for lv in levels]))
    figure, axes = new_figure(
        1, 2, height_in=3.2, title='mean receptance magnitude per force level'
    )
    for index, level in enumerate(levels):
        band = level.frequency_hz <= top_hz
        for ax in axes:
            ax.plot(
                level.frequency_hz[band],
                np.abs(level.receptance[band]) * MM_PER_M,
                color=level_colour(index),
                linewidth=1.2,
                label=f'{level.level} ({level.count} trials, {level.mean_impulse_n_s:.3g} N·s)',
            )
    axes[1].set_yscale('log')
    for ax, scale in zip(axes, ('', ', log'), strict=True):
        ax.set_xlim(0, top_hz)
        ax.set_xlabel(FREQUENCY_LABEL)
        ax.set_ylabel(f'|receptance| [{RECEPTANCE_DISPLAY_UNIT}]{scale}')
    axes[0].legend(loc='upper right', fontsize='small')
    return figure


def impulse_figure(
    impacts: Sequence[ImpactAnalysis],
    levels: Sequence[LevelSummary],
    nominal: Sequence[NominalLevel] = (),
) -> Figure:
    """Peak force of every hit by level, and each level's mean impulse +-1 sigma (Fig. 13)."""
    figure, axes = new_figure(1, 2, height_in=3.2, title='impact force levels and impulses')
    colours = {level.level: level_colour(index) for index, level in enumerate(levels)}
    for level in nominal:
        axes[0].axhspan(
            level.peak_force_n - level.tolerance_n,
            level.peak_force_n + level.tolerance_n,
            color='0.85',
            zorder=0,
        )
    numbers = np.arange(len(impacts))
    peaks = np.array([impact.peak_force_n for impact in impacts])
    accepted = np.array([impact.accepted for impact in impacts], dtype=bool)
    for name, colour in colours.items():
        mine = accepted & np.array([impact.level == name for impact in impacts], dtype=bool)
        axes[0].plot(numbers[mine], peaks[mine], 'o', color=colour, markersize=4, label=name)
    if (~accepted).any():
        axes[0].plot(
            numbers[~accepted],
            peaks[~accepted],
            'x',
            color=REJECTED_COLOUR,
            markersize=6,
            label='rejected',
        )
    axes[0].set_xlabel('hit number')
    axes[0].set_ylabel(schema.label(schema.PEAK_FORCE))
    axes[0].legend(fontsize='small', loc='best')
    x = np.arange(len(levels))
    means = [level.mean_impulse_n_s for level in levels]
    sigmas = [0.0 if np.isnan(level.std_impulse_n_s) else level.std_impulse_n_s for level in levels]
    for index in range(len(levels)):
        axes[1].errorbar(
            x[index],
            means[index],
            yerr=sigmas[index],
            fmt='o',
            capsize=5,
            color=level_colour(index),
        )
        axes[1].annotate(
            f'{means[index]:.3g} ± {sigmas[index]:.2g}',
            (x[index], means[index]),
            textcoords='offset points',
            xytext=(8, -3),
            fontsize='small',
        )
    axes[1].set_xticks(x, [f'{level.level}\n(n = {level.count})' for level in levels])
    axes[1].set_xlim(-0.5, len(levels) - 0.5 + 0.6)
    axes[1].set_ylabel(f'{schema.label(schema.IMPULSE)}, mean ± 1σ')
    return figure


def linearity_figure(summary: Summary) -> Figure:
    """Peak |receptance| against impulse, hits and level means, with the line and R² (Fig. 17)."""
    figure, axes = new_figure(1, 1, height_in=3.4, title='impulse versus peak receptance magnitude')
    ax = axes[0]
    for index, level in enumerate(summary.levels):
        colour = level_colour(index)
        hits = [
            impact for impact in summary.impacts if impact.accepted and impact.level == level.level
        ]
        ax.plot(
            [hit.impulse_n_s for hit in hits],
            [hit.peak_receptance_m_per_n * MM_PER_M for hit in hits],
            '.',
            color=colour,
            alpha=0.5,
            markersize=5,
        )
        ax.plot(
            level.mean_impulse_n_s,
            level.peak_receptance_m_per_n * MM_PER_M,
            '+',
            color=colour,
            markersize=14,
            markeredgewidth=2,
            label=f'{level.level} mean',
        )
    fit = summary.linearity
    if np.isfinite(fit.slope):
        impulses = [level.mean_impulse_n_s for level in summary.levels]
        span = np.array([min(impulses), max(impulses)])
        span = span + np.array([-0.1, 0.1]) * max(np.ptp(span), 0.05 * span.mean())
        r2 = f', R² = {fit.r2:.4f}' if np.isfinite(fit.r2) else ''
        ax.plot(
            span,
            (fit.slope * span + fit.intercept) * MM_PER_M,
            color=MEAN_COLOUR,
            linewidth=1,
            label=f'{fit.slope * MM_PER_M:.3g} mm/(N²·s) × I + '
            f'{fit.intercept * MM_PER_M:.3g} mm/N{r2}',
        )
    ax.set_xlabel(schema.label(schema.IMPULSE, words='impulse I'))
    ax.set_ylabel(f'peak |receptance| [{RECEPTANCE_DISPLAY_UNIT}]')
    ax.legend(fontsize='small', loc='upper left')
    return figure


def harmonics_figure(
    levels: Sequence[LevelSummary],
    model_mobility: Mapping[str, np.ndarray] | None = None,
    *,
    model_label: str = 'model',
    top_hz: float = HARMONICS_TOP_HZ,
) -> Figure:
    """Log |mobility| to 20 Hz per level, odd multiples of f_n marked (Fig. 24).

    The friction contact puts response at 3, 5, 7, ... f_n; a second structural mode would
    sit elsewhere. f_n is the level's, as the analysis gives it (the same number as in every
    table). With a model, its mobility is drawn over the measured one.
    """
    model_mobility = model_mobility or {}
    figure, axes = new_figure(
        len(levels), 1, sharex=True, title='mobility magnitude with the odd harmonics of f_n'
    )
    for index, (ax, level) in enumerate(zip(axes, levels, strict=True)):
        band = (level.frequency_hz > 0) & (level.frequency_hz <= top_hz)
        frequency = level.frequency_hz[band]
        ax.semilogy(
            frequency,
            np.abs(level.mobility[band]) * MM_PER_M,
            color=level_colour(index),
            linewidth=2.0,
            alpha=0.7,
            label=f'{level.level} measured',
        )
        if level.level in model_mobility:
            ax.semilogy(
                frequency,
                np.abs(model_mobility[level.level][band]) * MM_PER_M,
                color=MODEL_COLOUR,
                linewidth=0.8,
                linestyle='--',
                label=model_label,
            )
        natural_hz = level.natural_frequency_hz
        for n, harmonic_hz in odd_harmonics(natural_hz, top_hz):
            ax.axvline(harmonic_hz, color='0.4', linewidth=0.6, linestyle=':')
            left = harmonic_hz > 0.9 * top_hz
            ax.annotate(
                f'{n}$f_n$',
                (harmonic_hz, 1.0),
                xycoords=('data', 'axes fraction'),
                xytext=(-2 if left else 2, -10),
                textcoords='offset points',
                ha='right' if left else 'left',
                fontsize='x-small',
                color='0.3',
            )
        ax.set_ylabel(f'|mobility|\n[{MOBILITY_DISPLAY_UNIT}]')
        ax.legend(loc='lower left', fontsize='x-small')
        ax.set_title(
            f'f_n = {natural_hz:.4f} Hz '
            f'({frf.NATURAL_FREQUENCY_METHODS.get(level.natural_frequency_method, "none")})',
            fontsize='small',
            loc='right',
        )
    axes[-1].set_xlim(0, top_hz)
    axes[-1].set_xlabel(FREQUENCY_LABEL)
    return figure


def frf_overlay_figure(
    level: LevelSummary,
    model_mobility: np.ndarray,
    *,
    model_label: str = 'model',
    colour: str = 'tab:blue',
    top_hz: float | None = None,
) -> Figure:
    """Real and imaginary mobility, measured mean against the model (Figs. 19, 21, 23)."""
    top_hz = top_hz or resonance_top_hz(level.natural_frequency_hz)
    figure, axes = new_figure(
        2, 1, sharex=True, title=f'mobility, level {level.level}: measured and model'
    )
    band = level.frequency_hz <= top_hz
    frequency = level.frequency_hz[band]
    for ax, part, name in zip(axes, (np.real, np.imag), ('real', 'imaginary'), strict=True):
        ax.plot(
            frequency,
            part(level.mobility[band]) * MM_PER_M,
            color=colour,
            linewidth=2.0,
            alpha=0.7,
            label=f'measured mean ({level.count} trials)',
        )
        ax.plot(
            frequency,
            part(model_mobility[band]) * MM_PER_M,
            color=MODEL_COLOUR,
            linewidth=1.0,
            linestyle='--',
            label=model_label,
        )
        ax.set_ylabel(f'{name} [{MOBILITY_DISPLAY_UNIT}]')
    axes[0].legend(loc='upper right', fontsize='small')
    axes[1].set_xlabel(FREQUENCY_LABEL)
    axes[1].set_xlim(0, top_hz)
    return figure


def friction_figure(
    impulses_n_s: Sequence[float],
    mus: Sequence[float],
    stderrs: Sequence[float],
    levels: Sequence[str],
    joint_mu: float,
    joint_stderr: float,
    *,
    level_order: Sequence[str] = (),
) -> Figure:
    """Each impact's own mu +-1 sigma against its impulse, and the one mu fitted to all.

    The paper's claim (Sec. 5) is that one mu serves every level: the per-impact values then
    scatter about the joint one within their errors, whatever the impulse.
    """
    figure, axes = new_figure(
        1, 1, height_in=3.6, title='friction coefficient per impact and for all impacts'
    )
    ax = axes[0]
    impulses, values, errors = (np.asarray(a, dtype=float) for a in (impulses_n_s, mus, stderrs))
    span = np.array([np.nanmin(impulses), np.nanmax(impulses)])
    span = span + np.array([-0.05, 0.05]) * max(np.ptp(span), 0.1)
    ax.fill_between(span, joint_mu - joint_stderr, joint_mu + joint_stderr, color='0.85', zorder=0)
    ax.plot(
        span,
        [joint_mu, joint_mu],
        color=MEAN_COLOUR,
        linewidth=1,
        label=f'all impacts: μ = {format_with_uncertainty(joint_mu, joint_stderr)}',
    )
    names = list(level_order) + sorted(set(levels) - set(level_order))
    for name in names:
        mine = np.array([level == name for level in levels], dtype=bool)
        colour = level_colour(level_order.index(name)) if name in level_order else REJECTED_COLOUR
        ax.errorbar(
            impulses[mine],
            values[mine],
            yerr=errors[mine],
            fmt='o',
            markersize=4,
            capsize=3,
            color=colour,
            label=name or 'no level',
        )
    ax.set_xlim(*span)
    ax.set_xlabel(schema.label(schema.IMPULSE))
    ax.set_ylabel('μ [-], ± 1σ')
    ax.ticklabel_format(axis='y', style='plain', useOffset=False)
    # Under the axes (the error bars fill them): the layout keeps the axes above it.
    figure.legend(fontsize='small', loc='lower center', ncols=len(names) + 1)
    return figure


def running_mu_figure(
    mus: Sequence[float],
    stderrs: Sequence[float],
    own_mus: Sequence[float],
    own_stderrs: Sequence[float],
) -> Figure:
    """The running mu +- 1 sigma against hit number, as the fitter publishes it live.

    mus, stderrs: the estimate after each accepted hit (the hits' own mus, inverse-variance
    weighted); own_mus, own_stderrs: each hit's own, drawn beside it, so a level that
    disagrees shows as it comes.
    """
    figure, axes = new_figure(1, 1, height_in=3.2, title='running μ as the hits came in')
    ax = axes[0]
    hits = np.arange(1, len(mus) + 1)
    running, sigma = np.asarray(mus, dtype=float), np.asarray(stderrs, dtype=float)
    ax.fill_between(hits, running - sigma, running + sigma, color='0.85', step='mid')
    ax.plot(
        hits, running, color=MEAN_COLOUR, linewidth=1, drawstyle='steps-mid', label='running μ ± 1σ'
    )
    ax.errorbar(
        hits,
        own_mus,
        yerr=own_stderrs,
        fmt='o',
        markersize=3,
        capsize=2,
        color=level_colour(0),
        label="the hit's own μ ± 1σ",
    )
    ax.set_xlabel('accepted hit [-]')
    ax.set_ylabel('μ [-]')
    ax.ticklabel_format(axis='y', style='plain', useOffset=False)
    ax.legend(fontsize='small', loc='upper right')
    return figure


def resonance_top_hz(natural_frequency_hz: float) -> float:
    """Upper frequency of the resonance figures: RESONANCE_SPAN x f_n (5 Hz without f_n)."""
    if not np.isfinite(natural_frequency_hz) or natural_frequency_hz <= 0:
        return 5.0
    return RESONANCE_SPAN * natural_frequency_hz


def _force_zoom(
    ax,
    records: Sequence[ImpactRecord],
    triggers: Sequence[int],
    colours: Sequence[str],
    capture: CaptureConfig,
) -> None:
    """Force around the contact [ms from trigger] of every record, on one axes."""
    start_s, end_s = _force_window(records, triggers, capture)
    for record, trigger, colour in zip(records, triggers, colours, strict=True):
        plot_trace(
            ax,
            *_force_trace(record, trigger, start_s, end_s),
            color=colour,
            linewidth=0.8,
            alpha=0.8 if len(records) > 1 else 1.0,
        )
    ax.set_xlim(start_s * MS_PER_S, end_s * MS_PER_S)
    _force_labels(ax)


def _force_window(
    records: Sequence[ImpactRecord], triggers: Sequence[int], capture: CaptureConfig
) -> tuple[float, float]:
    """Start and end of the force zoom [s from trigger]: every pulse within min_spacing."""
    start_s, end_s = 0.0, 0.0
    for record, trigger in zip(records, triggers, strict=True):
        rate = record.sample_rate_hz
        force = record.force_n
        near = slice(
            max(trigger - int(capture.pretrigger_s * rate), 0),
            trigger + int(capture.min_spacing_s * rate),
        )
        touching = np.flatnonzero(force[near] >= capture.rearm_level_n) + near.start
        if touching.size:
            start_s = min(start_s, (touching[0] - trigger) / rate)
            end_s = max(end_s, (touching[-1] - trigger) / rate)
    start_s -= FORCE_MARGIN_S
    end_s += FORCE_MARGIN_S + 0.5 * (end_s - start_s)
    return start_s, end_s


def _force_trace(
    record: ImpactRecord, trigger: int, start_s: float, end_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Time [ms from trigger] and force [N] of the record from start_s to end_s."""
    rate = record.sample_rate_hz
    first = max(trigger + int(np.floor(start_s * rate)), 0)
    last = min(trigger + int(np.ceil(end_s * rate)) + 1, record.force_n.size)
    return (np.arange(first, last) - trigger) / rate * MS_PER_S, record.force_n[first:last]


def _decay_span(record: ImpactRecord, trigger: int, end_s: float) -> tuple[np.ndarray, slice]:
    """Time [s from trigger] of the record's samples up to end_s, and their slice."""
    rate = record.sample_rate_hz
    shown = slice(0, min(record.velocity_m_s.size, trigger + int(np.floor(end_s * rate)) + 1))
    return (np.arange(shown.stop) - trigger) / rate, shown


def _force_labels(ax) -> None:
    ax.set_xlabel('time from trigger [ms]')
    ax.set_ylabel('force [N]')


def _frf_unit(quantity: str) -> str:
    """Display unit of an FRF quantity (both are shown in mm per N, per N*s)."""
    if quantity == 'mobility':
        return MOBILITY_DISPLAY_UNIT
    if quantity == 'receptance':
        return RECEPTANCE_DISPLAY_UNIT
    raise BadInputError(f"unknown FRF quantity {quantity!r}; use 'mobility' or 'receptance'")


def source_name(source: str) -> str:
    """The last path component of a record's source, for titles and tables."""
    return source.replace('\\', '/').rsplit('/', 1)[-1] if source else ''
