"""Figures of a model diagnosis (`fmm_ros.core.diagnose`): the gap, and the friction law.

One row per impact. The residual figure shows measured minus model velocity over the motion
for the base model (Eq. 3) and for the model with the named effects; the mobility figure
shows |mobility| of the measurement and both models to 20 Hz, and beside it |measured -
model|, where the gap shows, with f_n and its odd harmonics marked. The friction map shows
mu against sliding speed and against position, with its standard errors. Used by the
report's diagnosis section and by `fmm diagnose -o DIR`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from fmm_ros.constants import MM_PER_M, MOBILITY_DISPLAY_UNIT
from fmm_ros.core.diagnose.gaps import motion_window
from fmm_ros.core.diagnose.result import Diagnosis
from fmm_ros.core.diagnose.workflow import UNEXPLAINED
from fmm_ros.core.signal import frf
from fmm_ros.report.plotting import (
    FREQUENCY_LABEL,
    MODEL_COLOUR,
    new_figure,
    plot_trace,
)
from fmm_ros.report.session_figures import HARMONICS_TOP_HZ, source_name

BASE_COLOUR = '0.55'


def model_effects(diagnosis: Diagnosis) -> tuple[str, ...]:
    """The effects in the final model (none: it is the base model)."""
    return tuple(e for e in diagnosis.named_effects if e != UNEXPLAINED)


def named_label(diagnosis: Diagnosis) -> str:
    """Legend text of the final model."""
    effects = model_effects(diagnosis)
    return f'with {" + ".join(effects)}' if effects else 'base model'


def residual_figure(
    diagnosis: Diagnosis, records: Sequence, rows: Sequence[int] | None = None
) -> Figure:
    """Measured minus model velocity over the motion, base and named model, per impact.

    records are the impacts diagnosed (anything with force_n, velocity_m_s and sample_rate_hz,
    as `diagnose` takes), in the diagnosis' order; rows picks which to draw (default all).
    """
    rows = range(len(records)) if rows is None else rows
    figure, axes = new_figure(
        len(rows),
        1,
        sharex=True,
        title=(
            f'measured minus model velocity: gap {diagnosis.gap_before:.3g} → '
            f'{diagnosis.gap_after:.3g} ({", ".join(diagnosis.named_effects) or "none"})'
        ),
    )
    for ax, row in zip(axes, rows, strict=True):
        record = records[row]
        before = diagnosis.base_residuals_m_s[row]
        after = diagnosis.named_residuals_m_s[row]
        time_s = np.arange(before.size) / record.sample_rate_hz
        end = motion_window(record.velocity_m_s - before, 0, record.sample_rate_hz).stop
        plot_trace(
            ax,
            time_s[:end],
            before[:end] * MM_PER_M,
            color=BASE_COLOUR,
            linewidth=0.6,
            label='base model',
        )
        if model_effects(diagnosis):
            plot_trace(
                ax,
                time_s[:end],
                after[:end] * MM_PER_M,
                color=MODEL_COLOUR,
                linewidth=0.6,
                label=named_label(diagnosis),
            )
        ax.set_ylabel('residual [mm/s]')
        ax.set_title(_name(record, row), fontsize='small')
        ax.legend(loc='upper right', fontsize='x-small')
    axes[-1].set_xlabel('time from record start [s]')
    return figure


def mobility_gap_figure(
    diagnosis: Diagnosis,
    records: Sequence,
    natural_frequency_hz: float,
    rows: Sequence[int] | None = None,
    top_hz: float = HARMONICS_TOP_HZ,
) -> Figure:
    """|mobility| of measurement and models, and |measured - model|, per impact, to 20 Hz."""
    rows = range(len(records)) if rows is None else rows
    figure, axes = new_figure(
        len(rows),
        2,
        sharex=True,
        title=(
            f'mobility: misfit {diagnosis.frf_gap_before:.3g} → {diagnosis.frf_gap_after:.3g} '
            f'({", ".join(diagnosis.named_effects) or "none"}); dotted: f_n and its odd harmonics'
        ),
    )
    axes = axes.reshape(len(rows), 2)
    for (overlay, error), row in zip(axes, rows, strict=True):
        record = records[row]
        before = diagnosis.base_residuals_m_s[row]
        frequency = frf.frequency_axis(before.size, record.sample_rate_hz)
        band = (frequency > 0.0) & (frequency <= top_hz)
        measured = frf.mobility(*frf.spectra(record.force_n, record.velocity_m_s))[band]
        curves = [('base model', before, BASE_COLOUR)]
        if model_effects(diagnosis):
            curves.append(
                (named_label(diagnosis), diagnosis.named_residuals_m_s[row], MODEL_COLOUR)
            )
        overlay.semilogy(
            frequency[band],
            np.abs(measured) * MM_PER_M,
            color='black',
            linewidth=0.8,
            linestyle=':',
            label='measured',
            zorder=3,
        )
        for label, residual, colour in curves:
            model = frf.mobility(*frf.spectra(record.force_n, record.velocity_m_s - residual))[band]
            overlay.semilogy(
                frequency[band], np.abs(model) * MM_PER_M, color=colour, linewidth=0.8, label=label
            )
            error.semilogy(
                frequency[band],
                np.abs(measured - model) * MM_PER_M,
                color=colour,
                linewidth=0.8,
                label=label,
            )
        for ax in (overlay, error):
            for harmonic in range(1, int(top_hz / natural_frequency_hz) + 1, 2):
                ax.axvline(
                    harmonic * natural_frequency_hz, color='0.4', linewidth=0.5, linestyle=':'
                )
            ax.legend(loc='upper right', fontsize='x-small')
        name = _name(record, row)
        overlay.set_title(f'{name}: |mobility|', fontsize='small')
        error.set_title(f'{name}: |measured − model|', fontsize='small')
        overlay.set_ylabel(f'[{MOBILITY_DISPLAY_UNIT}]')
    for ax in axes[-1]:
        ax.set_xlabel(FREQUENCY_LABEL)
        ax.set_xlim(0, top_hz)
    return figure


def friction_map_figure(diagnosis: Diagnosis) -> Figure:
    """Friction against sliding speed (log axis) and against position, +-1 sigma error bars.

    The dashed line is the base fit's single mu: a Coulomb contact's map lies on it.
    """
    figure, (by_speed, by_position) = new_figure(
        1,
        2,
        title='friction the records show (inverse dynamics, all hits): mu ± 1σ; dashed: base fit',
    )
    curves = (
        (by_speed, diagnosis.friction_map.speed, 'sliding speed [mm/s]'),
        (by_position, diagnosis.friction_map.position, 'position [mm]'),
    )
    for ax, curve, label in curves:
        if curve.mu:
            ax.errorbar(
                np.asarray(curve.centres) * MM_PER_M,
                curve.mu,
                yerr=curve.mu_stderr,
                color=MODEL_COLOUR,
                marker='o',
                markersize=3,
                linewidth=0.8,
                capsize=2,
            )
        else:
            ax.text(0.5, 0.5, 'no sliding above the noise', ha='center', transform=ax.transAxes)
        ax.axhline(diagnosis.mu, color=BASE_COLOUR, linestyle='--', linewidth=0.8)
        ax.set_xlabel(label)
        ax.set_ylabel('μ [-]')
    if diagnosis.friction_map.speed.mu:
        by_speed.set_xscale('log')
    return figure


def _name(record, row: int) -> str:
    """A record's file name (CSV records and bag records have a source), else its row."""
    return source_name(getattr(record, 'source', '')) or f'impact {row}'
