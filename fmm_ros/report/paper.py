"""The paper's simulation figures (Figs. 2-10) from the physics core, and their report page.

Sec. 3 of the paper studies a 1 kg, 5000 N/m Coulomb oscillator with mu = 0.1 (N = m g,
f_n = 11.25 Hz): free vibration from 3 mm and 1 mm (Figs. 2, 3), final against initial
displacement (Fig. 4), and the response to a 100 N rectangular pulse of 2.5, 5 and 10 ms
(Figs. 5-7) or to a 10 ms pulse with mu = 0.05, 0.1, 0.2 (Figs. 8-10), with 25 s records.
The paper integrated with Euler steps 10^4 times shorter than the period; the exact
integrator needs no such step, so everything runs at 10 kHz.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from fmm_ros.constants import MM_PER_M, RECEPTANCE_DISPLAY_UNIT, REPORT_DPI, SAMPLE_RATE_HZ
from fmm_ros.core.physics.model import Simulation, free_vibration, simulate
from fmm_ros.core.physics.rig import Rig
from fmm_ros.core.signal import frf
from fmm_ros.errors import BadInputError
from fmm_ros.report.html import Page
from fmm_ros.report.plotting import (
    FREQUENCY_LABEL,
    MS_PER_S,
    level_colour,
    new_figure,
)
from fmm_ros.sim.excitation import rectangular_pulse

PAPER_OSCILLATOR = Rig(
    mass_kg=1.0, stiffness_n_per_m=5000.0, damping_n_s_per_m=0.0, normal_force_n=1.0 * 9.81
)
"""The Sec. 3 example: m = 1 kg, k = 5000 N/m, no viscous damping, N = m g."""
PAPER_OSCILLATOR_MU = 0.1
FREE_VIBRATION_S = 0.6
PULSE_RECORD_S = 25.0
PULSE_FORCE_N = 100.0
PULSE_START_S = 1e-3
PULSE_DURATIONS_S = (2.5e-3, 5e-3, 10e-3)
FRICTION_STUDY_MU = (0.05, 0.1, 0.2)
# Fig. 4: initial displacements from 0 to 5 mm in 0.005 mm steps.
SWEEP_X0_M = np.linspace(0.0, 5e-3, 1001)
# Frequency range of Figs. 6, 7, 9, 10 [Hz] (f_n = 11.25 Hz), and their zoom near f_n.
SPECTRUM_TOP_HZ = 30.0
ZOOM_BAND_HZ = (9.0, 13.5)


@dataclass(frozen=True, eq=False)
class PulseResponse:
    """One simulated pulse test: force [N] and displacement [m] records and their spectra.

    Spectra are DFTs divided by the sample rate, i.e. the continuous Fourier transform of
    the record (force in N/Hz = N*s, displacement in m/Hz), so a short pulse's force spectrum
    starts at its impulse.
    """

    label: str
    force_n: np.ndarray
    displacement_m: np.ndarray
    sample_rate_hz: float
    rest_position_m: float

    @property
    def time_s(self) -> np.ndarray:
        """Sample times [s]."""
        return np.arange(self.force_n.size) / self.sample_rate_hz

    @property
    def frequency_hz(self) -> np.ndarray:
        """One-sided DFT frequencies [Hz]."""
        return frf.frequency_axis(self.force_n.size, self.sample_rate_hz)

    @property
    def force_spectrum(self) -> np.ndarray:
        """Fourier transform of the force [N/Hz]."""
        return np.fft.rfft(self.force_n) / self.sample_rate_hz

    @property
    def displacement_spectrum(self) -> np.ndarray:
        """Fourier transform of the displacement [m/Hz]."""
        return np.fft.rfft(self.displacement_m) / self.sample_rate_hz

    @property
    def receptance(self) -> np.ndarray:
        """X/F [m/N], the paper's receptance from displacement; NaN where F is 0 (sinc nulls)."""
        force = self.force_spectrum
        zero = force == 0
        return np.where(zero, np.nan, self.displacement_spectrum / np.where(zero, 1.0, force))


def pulse_response(
    pulse_duration_s: float,
    force_n: float = PULSE_FORCE_N,
    *,
    mu: float = PAPER_OSCILLATOR_MU,
    rig: Rig = PAPER_OSCILLATOR,
    label: str = '',
) -> PulseResponse:
    """The oscillator's response to a rectangular pulse over a 25 s record (Figs. 5-10)."""
    force = rectangular_pulse(
        force_n, pulse_duration_s, SAMPLE_RATE_HZ, PULSE_RECORD_S, start_s=PULSE_START_S
    )
    response = simulate(force, SAMPLE_RATE_HZ, rig=rig, mu=mu)
    return PulseResponse(
        label, force, response.displacement_m, SAMPLE_RATE_HZ, response.rest_position_m
    )


def rest_positions(
    x0_m: np.ndarray,
    *,
    mu: float = PAPER_OSCILLATOR_MU,
    rig: Rig = PAPER_OSCILLATOR,
    duration_s: float = 1.0,
) -> np.ndarray:
    """Final rest position [m] after release from each initial displacement (Fig. 4).

    Raises ValueError if a run is still moving at duration_s (too short to settle).
    """
    finals = np.empty(len(x0_m))
    for i, x0 in enumerate(x0_m):
        run = free_vibration(float(x0), duration_s, SAMPLE_RATE_HZ, mu=mu, rig=rig)
        if not run.at_rest:
            raise BadInputError(
                f'release from {x0 * MM_PER_M:g} mm has not come to rest after {duration_s:g} s'
            )
        finals[i] = run.rest_position_m
    return finals


def free_vibration_figure(run: Simulation, x0_m: float, limit_m: float) -> Figure:
    """Displacement with the +-x_lim rest band, and velocity, after a release (Figs. 2, 3)."""
    figure, axes = new_figure(
        2,
        1,
        sharex=True,
        title=f'free vibration from x0 = {x0_m * MM_PER_M:g} mm: '
        f'at rest at {run.rest_position_m * MM_PER_M:.3f} mm',
    )
    time_s = run.time_s
    axes[0].plot(time_s, run.displacement_m * MM_PER_M, color=level_colour(0), linewidth=1)
    for sign in (1, -1):
        axes[0].axhline(
            sign * limit_m * MM_PER_M,
            color='0.3',
            linestyle='--',
            linewidth=0.8,
            label='±x_lim = ±μN/k' if sign > 0 else None,
        )
    axes[0].legend(loc='upper right', fontsize='small')
    axes[0].set_ylabel('displacement [mm]')
    axes[1].plot(time_s, run.velocity_m_s, color=level_colour(1), linewidth=1)
    axes[1].set_ylabel('velocity [m/s]')
    axes[1].set_xlabel('time [s]')
    axes[1].set_xlim(0, time_s[-1])
    return figure


def rest_position_figure(x0_m: np.ndarray, final_m: np.ndarray, limit_m: float) -> Figure:
    """Final against initial displacement: a triangle wave of period 4 x_lim (Fig. 4)."""
    figure, axes = new_figure(
        1, 1, height_in=3.2, title='final versus initial displacement, free vibration'
    )
    axes[0].plot(x0_m * MM_PER_M, final_m * MM_PER_M, color=level_colour(0), linewidth=1)
    for sign in (1, -1):
        axes[0].axhline(
            sign * limit_m * MM_PER_M,
            color='0.3',
            linestyle='--',
            linewidth=0.8,
            label=f'±x_lim = ±{limit_m * MM_PER_M:.3f} mm' if sign > 0 else None,
        )
    # Room under the triangle wave for the legend.
    axes[0].set_ylim(-1.6 * limit_m * MM_PER_M, 1.2 * limit_m * MM_PER_M)
    axes[0].legend(loc='lower center', fontsize='small')
    axes[0].set_xlabel('initial displacement x0 [mm]')
    axes[0].set_ylabel('final displacement [mm]')
    axes[0].set_xlim(x0_m[0] * MM_PER_M, x0_m[-1] * MM_PER_M)
    return figure


def pulse_time_figure(
    responses: Sequence[PulseResponse], *, decay_s: float = 2.0, start_s: float | None = None
) -> Figure:
    """Force pulses [ms] over displacement [s] (Figs. 5, 8); start_s adds an early zoom."""
    rows = 3 if start_s else 2
    figure, axes = new_figure(rows, 1, title='rectangular force pulse and displacement')
    pulse_end_s = max(np.flatnonzero(r.force_n)[-1] / r.sample_rate_hz for r in responses)
    for index, response in enumerate(responses):
        colour = level_colour(index)
        time_s = response.time_s
        near = time_s <= 1.5 * pulse_end_s + PULSE_START_S
        axes[0].plot(
            time_s[near] * MS_PER_S,
            response.force_n[near],
            color=colour,
            linewidth=1,
            label=response.label,
        )
        shown = time_s <= decay_s
        axes[1].plot(
            time_s[shown],
            response.displacement_m[shown] * MM_PER_M,
            color=colour,
            linewidth=0.8,
            label=response.label,
        )
        if start_s:
            early = time_s <= start_s
            axes[2].plot(
                time_s[early],
                response.displacement_m[early] * MM_PER_M,
                color=colour,
                linewidth=1,
                label=response.label,
            )
    axes[0].set_xlabel('time [ms]')
    axes[0].set_ylabel('force [N]')
    axes[0].legend(loc='upper right', fontsize='small')
    for ax in axes[1:]:
        ax.set_xlabel('time [s]')
        ax.set_ylabel('displacement [mm]')
        ax.set_xlim(left=0)
    axes[1].set_xlim(right=decay_s)
    return figure


def pulse_spectra_figure(responses: Sequence[PulseResponse], *, zoom: bool = False) -> Figure:
    """|F| and |X| against frequency (Figs. 6, 9); zoom adds |X| near f_n."""
    rows = 3 if zoom else 2
    figure, axes = new_figure(rows, 1, title='force and displacement spectra')
    for index, response in enumerate(responses):
        colour = level_colour(index)
        frequency = response.frequency_hz
        band = frequency <= SPECTRUM_TOP_HZ
        axes[0].plot(
            frequency[band],
            np.abs(response.force_spectrum[band]),
            color=colour,
            linewidth=1,
            label=response.label,
        )
        magnitude = np.abs(response.displacement_spectrum) * MM_PER_M
        axes[1].plot(
            frequency[band], magnitude[band], color=colour, linewidth=1, label=response.label
        )
        if zoom:
            near = (frequency >= ZOOM_BAND_HZ[0]) & (frequency <= ZOOM_BAND_HZ[1])
            axes[2].plot(
                frequency[near],
                magnitude[near],
                color=colour,
                linewidth=1,
                marker='.',
                markersize=3,
                label=response.label,
            )
    axes[0].set_ylabel('|F| [N/Hz]')
    axes[0].set_ylim(bottom=0)
    axes[0].legend(loc='lower left', fontsize='small')
    axes[1].set_ylabel('|X| [mm/Hz]')
    for ax in axes[:2]:
        ax.set_xlim(0, SPECTRUM_TOP_HZ)
    if zoom:
        axes[2].set_ylabel('|X| [mm/Hz]')
        axes[2].set_xlim(*ZOOM_BAND_HZ)
    for ax in axes:
        ax.set_xlabel(FREQUENCY_LABEL)
    return figure


def pulse_receptance_figure(responses: Sequence[PulseResponse], *, zoom: bool = False) -> Figure:
    """Real and imaginary receptance X/F (Figs. 7, 10); zoom adds the imaginary near f_n."""
    rows = 3 if zoom else 2
    figure, axes = new_figure(rows, 1, title='receptance X/F')
    for index, response in enumerate(responses):
        colour = level_colour(index)
        frequency = response.frequency_hz
        band = (frequency > 0) & (frequency <= SPECTRUM_TOP_HZ)
        receptance = response.receptance * MM_PER_M
        axes[0].plot(
            frequency[band], receptance[band].real, color=colour, linewidth=1, label=response.label
        )
        axes[1].plot(
            frequency[band], receptance[band].imag, color=colour, linewidth=1, label=response.label
        )
        if zoom:
            near = (frequency >= ZOOM_BAND_HZ[0]) & (frequency <= ZOOM_BAND_HZ[1])
            axes[2].plot(
                frequency[near],
                receptance[near].imag,
                color=colour,
                linewidth=1,
                marker='.',
                markersize=3,
                label=response.label,
            )
    axes[0].set_ylabel(f'real [{RECEPTANCE_DISPLAY_UNIT}]')
    axes[1].set_ylabel(f'imaginary [{RECEPTANCE_DISPLAY_UNIT}]')
    axes[0].legend(loc='upper right', fontsize='small')
    for ax in axes[:2]:
        ax.set_xlim(0, SPECTRUM_TOP_HZ)
    if zoom:
        axes[2].set_ylabel(f'imaginary [{RECEPTANCE_DISPLAY_UNIT}]')
        axes[2].set_xlim(*ZOOM_BAND_HZ)
    for ax in axes:
        ax.set_xlabel(FREQUENCY_LABEL)
    return figure


def _free_vibration_section(page: Page, rig: Rig, mu: float) -> None:
    """Figs. 2-4: two releases from rest coming to rest, and rest against release position.

    The free vibration shows friction's dead band: the mass stops anywhere within +-x_lim.
    """
    limit_m = rig.friction_limit_m(mu)
    page.section('Free vibration (Figs. 2-4)', 'free')
    page.text(
        f'm = {rig.mass_kg:g} kg, k = {rig.stiffness_n_per_m:g} N/m, μ = {mu:g}, '
        f'N = m g = {rig.normal_force_n:g} N: f_n = {rig.natural_frequency_hz:.2f} Hz, '
        f'x_lim = μN/k = {limit_m * MM_PER_M:.4f} mm. Released at rest from x0.'
    )
    for number, x0_m, paper_mm in ((2, 3e-3, -0.139), (3, 1e-3, 0.176)):
        run = free_vibration(x0_m, FREE_VIBRATION_S, SAMPLE_RATE_HZ, mu=mu, rig=rig)
        page.figure(
            f'fig{number}_free_vibration_{x0_m * MM_PER_M:g}mm',
            free_vibration_figure(run, x0_m, limit_m),
            f'Fig. {number}: x0 = {x0_m * MM_PER_M:g} mm comes to rest at '
            f'{run.rest_position_m * MM_PER_M:.3f} mm (paper: {paper_mm} mm) after '
            f'{run.rest_time_s:.3f} s; dashed: ±x_lim.',
        )
    finals = rest_positions(SWEEP_X0_M, mu=mu, rig=rig)
    page.figure(
        'fig4_final_vs_initial',
        rest_position_figure(SWEEP_X0_M, finals, limit_m),
        f'Fig. 4: final against initial displacement, {SWEEP_X0_M.size} releases from '
        f'0 to {SWEEP_X0_M[-1] * MM_PER_M:g} mm: a triangle wave of period 4 μN/k = '
        f'{4 * limit_m * MM_PER_M:.3f} mm and amplitude x_lim.',
    )


def _pulse_section(page: Page, rig: Rig) -> None:
    """Figs. 5-7: one force for three pulse durations, in time, spectrum and receptance.

    The receptance changing with the impulse is what shows the system is not linear.
    """
    page.section('Rectangular pulse of three durations (Figs. 5-7)', 'pulse')
    widths = [
        pulse_response(width, label=f'Δt = {width * MS_PER_S:g} ms ({PULSE_FORCE_N * width:g} N·s)')
        for width in PULSE_DURATIONS_S
    ]
    page.text(
        f'{PULSE_FORCE_N:g} N for Δt, {PULSE_RECORD_S:g} s records at '
        f'{SAMPLE_RATE_HZ:g} Hz (frequency step {1 / PULSE_RECORD_S:g} Hz). The '
        'displacement peaks fall linearly (friction), not exponentially (viscous '
        'damping); the response grows with the impulse.'
    )
    page.figure(
        'fig5_pulse_durations',
        pulse_time_figure(widths),
        'Fig. 5: force input for three Δt (top, ms) and displacement output (bottom, s).',
    )
    page.figure(
        'fig6_pulse_spectra',
        pulse_spectra_figure(widths),
        'Fig. 6: force and displacement spectra; the response peaks at '
        f'f_n = {rig.natural_frequency_hz:.2f} Hz.',
    )
    page.figure(
        'fig7_pulse_receptance',
        pulse_receptance_figure(widths),
        'Fig. 7: real and imaginary receptance for three Δt: it depends on the energy '
        "put in, unlike a linear system's.",
    )


def _friction_section(page: Page) -> None:
    """Figs. 8-10: the longest pulse for three friction coefficients, as Figs. 5-7 show it.

    How the response changes with mu is what a fit of mu to a measured hit relies on.
    """
    page.section('Three friction coefficients (Figs. 8-10)', 'friction')
    width = PULSE_DURATIONS_S[-1]
    frictions = [
        pulse_response(width, mu=value, label=f'μ = {value:g}') for value in FRICTION_STUDY_MU
    ]
    page.text(
        f'{PULSE_FORCE_N:g} N for {width * MS_PER_S:g} ms '
        f'({PULSE_FORCE_N * width:g} N·s) with μ = '
        + ', '.join(f'{value:g}' for value in FRICTION_STUDY_MU)
        + '.'
    )
    page.figure(
        'fig8_friction_time',
        pulse_time_figure(frictions, decay_s=4.0, start_s=0.25),
        'Fig. 8: force input (top), displacement for three μ (middle) and its first '
        '0.25 s (bottom).',
    )
    page.figure(
        'fig9_friction_spectra',
        pulse_spectra_figure(frictions, zoom=True),
        'Fig. 9: force and displacement spectra, and the displacement magnitude near f_n (bottom).',
    )
    page.figure(
        'fig10_friction_receptance',
        pulse_receptance_figure(frictions, zoom=True),
        'Fig. 10: real and imaginary receptance for three μ, and the imaginary part near '
        'f_n (bottom).',
    )


def build_paper_report(out_dir: str | Path, *, dpi: float = REPORT_DPI) -> Path:
    """Write the paper's Figs. 2-10, reproduced by the physics core, as a report page."""
    rig, mu = PAPER_OSCILLATOR, PAPER_OSCILLATOR_MU
    page = Page(out_dir, 'Kossack, Ziegert, Schmitz (2019), Figs. 2-10 reproduced', dpi=dpi)
    _free_vibration_section(page, rig, mu)
    _pulse_section(page, rig)
    _friction_section(page)
    return page.write()
