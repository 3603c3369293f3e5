"""How results read as text: the tables `fmm` prints, one function per result type.

Shared by the subcommands that print the same result: analyze and replay (an analysis),
fit and `fmm ros call fit` (a `FrictionResult`), diagnose and `fmm ros call diagnose` (a
diagnosis as `diagnosis_dict` gives it, or the service's response in the same keys). Receptance
is shown in mm/N as in the report; JSON stays in SI.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from fmm_ros.constants import MM_PER_M, RECEPTANCE_DISPLAY_UNIT
from fmm_ros.core import results_schema as schema
from fmm_ros.core.results_schema import ASCII_PM, label
from fmm_ros.core.results_schema import format_with_uncertainty as pm

if TYPE_CHECKING:
    from fmm_ros.core.signal.analysis import Summary
    from fmm_ros.workflows.results import FrictionResult


def _short_ring_note(at_peak: Sequence) -> str:
    """The line under the impacts whose f_n (marked *) was read at a short ring's DFT peak."""
    values = ', '.join(
        f'{Path(r.source).name or r.impact_id} '
        + schema.format_with_uncertainty(
            r.natural_frequency_hz, r.natural_frequency_uncertainty_hz, ' +- '
        )
        + ' Hz'
        for r in at_peak
    )
    return f'* f_n at the DFT peak of a ring too short to time (one or two cycles): {values}'


def analysis_text(summary: Summary) -> str:
    """A table of impacts, one of levels, and the regression line (|X/F| in mm/N)."""
    import numpy as np

    from fmm_ros.core.signal import frf

    impulse = label(schema.IMPULSE, ascii=True)
    peak = label(schema.PEAK_FORCE, ascii=True, short=True)
    receptance = label(schema.PEAK_RECEPTANCE, ascii=True, short=True)
    natural = label(schema.NATURAL_FREQUENCY, ascii=True)
    lines = [
        f'{"impact":<28} {"level":<8} {"ok":<3} {impulse:>13} {peak:>8} '
        f'{receptance:>12} {natural:>8}  flags'
    ]
    at_peak = [r for r in summary.impacts if r.natural_frequency_method == frf.DFT_PEAK]
    for result in summary.impacts:
        mark = '*' if result in at_peak else ' '
        lines.append(
            f'{Path(result.source).name:<28.28} {result.level or "-":<8} '
            f'{"yes" if result.accepted else "no":<3} {result.impulse_n_s:>13.4g} '
            f'{result.peak_force_n:>8.4g} '
            f'{schema.PEAK_RECEPTANCE.cell(result.peak_receptance_m_per_n):>12} '
            f'{schema.NATURAL_FREQUENCY.cell(result.natural_frequency_hz):>8}{mark} '
            f'{",".join(result.flags) or "-"}'
        )
    if at_peak:
        lines.append(_short_ring_note(at_peak))
    mean_impulse = label(schema.MEAN_IMPULSE, ascii=True)
    lines += [
        '',
        f'{"level":<8} {"count":>5} {mean_impulse:>18} {receptance:>12} {natural:>8}',
    ]
    for level in summary.levels:
        lines.append(
            f'{level.level:<8} {level.count:>5} {level.mean_impulse_n_s:>18.4g} '
            f'{schema.PEAK_RECEPTANCE.cell(level.peak_receptance_m_per_n):>12} '
            f'{schema.NATURAL_FREQUENCY.cell(level.natural_frequency_hz):>8}'
        )
    if not summary.levels:
        lines.append('(no level has an accepted impact)')
    fit = summary.linearity
    lines.append('')
    if np.isnan(fit.slope):
        lines.append('linearity: needs accepted impacts at 2 or more levels')
    else:
        lines.append(
            f'linearity: |X/F| peak = {fit.slope * MM_PER_M:.4g} mm/(N^2*s) * impulse + '
            f'{fit.intercept * MM_PER_M:.4g} {RECEPTANCE_DISPLAY_UNIT} over {fit.count} levels, '
            f'R^2 = {fit.r2:.4f}'
        )
    return '\n'.join(lines)


def friction_text(result: FrictionResult) -> str:
    """A few lines for a person: the common mu, c, the residual, then one line per impact."""
    count = len(result.impact_ids)
    lines = [
        f'mu = {pm(result.mu, result.mu_stderr, ASCII_PM)}  (one mu for {count} '
        f'impact{"s" if count > 1 else ""}, {result.misfit} misfit)'
    ]
    if result.damping_fitted:
        lines.append(
            f'c  = {pm(result.damping_n_s_per_m, result.damping_stderr_n_s_per_m, ASCII_PM)} '
            'N*s/m (fitted)'
        )
    else:
        lines.append(f'c  = {result.damping_n_s_per_m:.4f} N*s/m (rig constant)')
    lines.append(
        f'residual {result.residual_rms_m_s:.3e} m/s RMS = '
        f'{100 * result.normalised_residual:.3f} % of the peak velocity '
        f'(velocity noise {result.noise_std_m_s:.3e} m/s)'
    )
    if result.velocity_nuisance:
        hum = sorted({n.mains_hz for n in result.velocity_nuisance if n.mains_hz})
        offsets = [n.offset_m_s for n in result.velocity_nuisance]
        lines.append(
            'velocity chain: '
            + (f'{"/".join(f"{h:g}" for h in hum)} Hz mains hum' if hum else 'no mains hum')
            + f' and an offset of {min(offsets):.2g} to {max(offsets):.2g} m/s taken off'
        )
    if result.impulse_scales:
        lines.append(
            f'hit impulses scaled by {min(result.impulse_scales):.4f} to '
            f'{max(result.impulse_scales):.4f} (fitted: the sampled force misstates them)'
        )
    if count > 1:
        verdict = (
            'serves all impacts'
            if result.consistency_p_value >= 0.01
            else 'does NOT serve all impacts'
        )
        lines.append(
            f'one mu {verdict}: chi^2 {result.consistency_chi2:.3g} over {count - 1} '
            f'degree{"s" if count > 2 else ""} of freedom, p = '
            f'{result.consistency_p_value:.3g}'
        )
    lines += [
        '',
        f'{"impact":<28} {label(schema.IMPULSE, ascii=True):>13} {"mu alone":>9} {"+-":>8} '
        f'{label(schema.RESIDUAL_RMS, ascii=True):>14}  (at the common mu)',
    ]
    for entry in result.per_impact():
        lines.append(
            f'{Path(entry["file"]).name:<28.28} {entry[schema.IMPULSE.name]:>13.4f} '
            f'{entry["mu"]:>9.5f} {entry["mu_stderr"]:>8.2g} {entry["residual_rms_m_s"]:>14.3e}'
        )
    return '\n'.join(lines)


def diagnosis_text(payload: dict, impacts: int, figures: Sequence[Path] = ()) -> str:
    """The short tables a person reads in half a minute, from `diagnosis_dict` (or a service's)."""
    from fmm_ros.core.diagnose.vocabulary import NONE  # the model terms: not for a replay
    from fmm_ros.workflows.results import detection_limit_text  # numpy: not at CLI start-up

    result = payload
    lines = [
        f'{impacts} impact(s); velocity noise {result["noise_std_m_s"]:.3g} m/s (from the '
        f'data; {result["residual_noise_std_m_s"]:.3g} m/s where the rig rests, which the gaps '
        f'are beyond); starts {result["starts"]}; '
        f'base fit mu = {_value(result["mu"], result["mu_stderr"], "1")}'
    ]
    named = result['missing_effects']
    lines.append(
        f'missing effects: {", ".join(n["effect"] for n in named) or NONE}   gap '
        f'{result["gap_before"]:.3g} -> {_finite(result["gap_after"]):.3g}   FRF gap '
        f'{_finite(result["frf_gap_before"]):.3g} -> {_finite(result["frf_gap_after"]):.3g}'
    )
    for entry in named:
        if 'where' in entry:
            lines.append(f'  {entry["effect"]}: {entry["where"]["summary"]}')
            continue
        partial = ', a partial description only' if entry['partial'] else ''
        lines.append(
            f'  {entry["effect"]}: score {_finite(entry["score"]):.0f}, dropping it again '
            f'would cost {_finite(entry["drop_score"]):.0f}{partial}'
        )
        if 'slope_per_hit' in entry:
            mus = entry['mu_per_hit']
            lines.append(
                f'    mu per hit {mus[0]:.4f} ... {mus[-1]:.4f}, slope '
                f'{_value(entry["slope_per_hit"], entry["slope_stderr"], "1")} per hit '
                f'(p = {_finite(entry["trend_p_value"]):.2g})'
            )
            continue
        for name, value in entry['parameters'].items():
            error, unit = entry['parameter_stderr'][name], entry['parameter_units'][name]
            bound = '  (at its bound)' if entry.get('parameter_at_bound', {}).get(name) else ''
            lines.append(f'    {name:<38} {_value(value, error, unit)}{bound}')
    lines.append(f'where (base model): {result["where"]["summary"]}')
    lines.append('')
    lines.append(
        f'{"candidate (step 1)":<22}{"score (dBIC)":>14}{"gap after":>12}{"shows from":>30}'
    )
    names = {entry['effect'] for entry in named}
    for candidate in result['candidates']:
        mark = '  <- named' if candidate['effect'] in names else ''
        if candidate.get('message', '').startswith('screened'):
            mark += '  (screened)'
        score = _finite(candidate['score'])
        score = f'{score:.0f}' if math.isfinite(score) else 'failed'
        gap = _finite(candidate['gap_after'])
        shows = detection_limit_text(candidate.get('detection_limit'))
        lines.append(f'{candidate["effect"]:<22}{score:>14}{gap:>12.3g}{shows:>30}{mark}')
    lines.append(
        f'(an effect is added when dBIC <= {result["required_score"]:.0f} and it removes a '
        'quarter of the squared gap left; the named set must halve the gap; "shows from": the '
        'size at which these records would show the effect, so a smaller one can hide here)'
    )
    lines += result['selection']
    lines.append(_friction_line(result['friction_map']))
    lines.append(result['verdict'])
    lines += [f'wrote {path}' for path in figures]
    return '\n'.join(lines)


def _friction_line(friction_map: dict) -> str:
    """Friction at the slowest and fastest speed bins, and its range over position."""
    speed, position = friction_map['speed'], friction_map['position']
    if not speed['mu']:
        return 'friction map: no sliding above the noise'
    text = (
        f'friction map: mu {_value(speed["mu"][0], speed["mu_stderr"][0], "1")} at '
        f'{1e3 * speed["speed_m_s"][0]:.3g} mm/s, '
        f'{_value(speed["mu"][-1], speed["mu_stderr"][-1], "1")} at '
        f'{1e3 * speed["speed_m_s"][-1]:.3g} mm/s'
    )
    if position['mu']:
        text += f'; {min(position["mu"]):.4f} to {max(position["mu"]):.4f} over position'
    return text


def _finite(value: float | None) -> float:
    """A JSON number back as a float (null: NaN)."""
    return math.nan if value is None else float(value)


def _value(value: float, error: float | None, unit: str) -> str:
    """Value +- error unit by the one rule (`format_with_uncertainty`); unknown error: none."""
    error = _finite(error)
    unit = '' if unit == '1' else f' {unit}'
    return f'{pm(value, error, ASCII_PM)}{unit}'
