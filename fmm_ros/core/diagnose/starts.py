"""Where each candidate is probed and refitted from: the signature that points at its effect.

Added damping from the peak-map slope, asymmetry from the centre shift, k3 from the period
slope, offset from the rest velocity, delay from the phase slope; Stribeck at three speeds
v_s; the second mode at the strongest residual peak with three damping ratios. These are
probes: the screen (`screen`) scales each by regression on the residual, and the best,
scaled, is where a refit starts.
"""

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from fmm_ros.core.diagnose import signatures as discrepancy
from fmm_ros.core.diagnose.result import Where
from fmm_ros.core.identify.conditioning import ConditionedImpact
from fmm_ros.core.physics.rig import Rig
from fmm_ros.core.physics.terms import EFFECT_SIZE, MODEL_TERMS, ModelTerm, model_term
from fmm_ros.core.signal.config import AnalysisConfig
from fmm_ros.core.signal.frf import excitation_bandwidth
from fmm_ros.errors import BadInputError

STRIBECK_PROBE_SPEEDS_M_S = (1e-3, 3e-3, 1e-2)
"""Stribeck speeds v_s probed: the plausible range (0.1-50 mm/s) where a decay of a few
hundred mm/s down to rest can tell them apart."""


STRIBECK_PROBE_EXCESS = 0.02
"""Static friction excess of the Stribeck probes [-] (the screen scales it)."""


SECOND_MODE_DAMPING_RATIOS = (3e-3, 1e-2, 3e-2)
"""Damping ratios probed for the second mode (its modal mass is what the screen scales)."""


MODE_PEAK_SIGMAS = 8.0
"""A residual peak must stand this many noise deviations out for a second mode to be probed
there (the significance the base model's `where` reports peaks at)."""


MODE_PEAKS = 3
"""The second mode is probed at this many of the strongest peaks: mains hum (50 Hz and its
harmonics) can stand out more than a weak mode, and no mode reproduces a steady tone."""


MODE_LIMIT_FREQUENCIES = 8
"""The second mode's detection limit is taken at this many frequencies, log-spaced over the
band a mode is probed in, up to where the hits' excitation runs out (`mode_limit_probes`)."""


def probes(
    effect: str,
    impacts: Sequence[ConditionedImpact],
    residuals: Sequence[np.ndarray],
    noise_std_m_s: float,
    where: Where,
    rig: Rig,
    ranges: Mapping[str, tuple[float, float]] | None = None,
) -> tuple[ModelTerm, ...]:
    """The shapes of one candidate to screen, each at a size that moves the response.

    Stribeck at each of STRIBECK_PROBE_SPEEDS_M_S; the second mode at each of the MODE_PEAKS
    strongest peaks of the residual above 1.5 f_n, inside the term's frequency bounds,
    standing MODE_PEAK_SIGMAS noise deviations out of it (none
    without one: a mode rings narrow-band), with each damping ratio and 1 kg; every
    other term at its start from the signatures (`start_term`), or at its default size where
    the signature points at none. ranges: the session's fitting ranges (`physical_ranges`),
    which the starts are clipped into.
    """
    cls = MODEL_TERMS[effect]
    if effect == 'stribeck':
        return tuple(
            cls(mu_static_excess=STRIBECK_PROBE_EXCESS, stribeck_velocity_m_s=speed)
            for speed in STRIBECK_PROBE_SPEEDS_M_S
        )
    if effect == 'second_mode':
        low, high = cls.bounds()
        peaks = discrepancy.non_harmonic_peaks(
            residuals,
            impacts[0].sample_rate_hz,
            rig.natural_frequency_hz,
            noise_std_m_s,
            lowest_hz=max(1.5 * rig.natural_frequency_hz, float(low[0])),
            highest_hz=min(float(high[0]), 0.45 * impacts[0].sample_rate_hz),
            count=MODE_PEAKS,
            threshold=MODE_PEAK_SIGMAS,
            skip_harmonics=False,
        )
        return tuple(
            model_term(
                effect, frequency_hz=peak.frequency_hz, damping_ratio=zeta, modal_mass_kg=1.0
            )
            for peak in peaks
            for zeta in SECOND_MODE_DAMPING_RATIOS
        )
    start = start_term(effect, impacts, where, rig, ranges)
    name, _ = EFFECT_SIZE[effect]
    if getattr(start, name) == 0.0:
        default = next(p.default for p in cls.parameters if p.name == name)
        start = replace(start, **{name: default})
    return (start,)


def mode_limit_probes(impacts: Sequence[ConditionedImpact], rig: Rig) -> tuple[ModelTerm, ...]:
    """The second modes a session's detection limit is taken over (`screen_term`).

    A mode at each of MODE_LIMIT_FREQUENCIES frequencies, log-spaced from where one is probed
    (1.5 f_n, the term's lowest frequency) to where the hits' force spectrum, summed, has
    dropped by the analysis's `excitation_drop_db` (the FRF's usable band: above it the hammer
    puts in too little for any mode to show), at the largest damping ratio probed and 1 kg.
    The limit is the lightest of their limits: the mode least visible in that band (heavier
    modes show at lower frequencies). Not the naming probes: those sit at the residual's
    peaks, and hum makes some in a clean session, while what could hide is a mode anywhere.
    () when the band is empty.
    """
    cls = MODEL_TERMS['second_mode']
    low, high = cls.bounds()
    rate = impacts[0].sample_rate_hz
    n_fft = 1 << math.ceil(math.log2(rate))  # 1 Hz bins or finer
    spectra = np.array(
        [np.fft.rfft(impact.force_n[: impact.hit_end_index], n_fft) for impact in impacts]
    )
    excited = excitation_bandwidth(
        spectra, np.fft.rfftfreq(n_fft, 1.0 / rate), AnalysisConfig().excitation_drop_db
    )
    lowest = max(1.5 * rig.natural_frequency_hz, float(low[0]))
    highest = min(float(high[0]), 0.45 * rate, excited)
    if not highest > lowest:
        return ()
    return tuple(
        model_term(
            'second_mode',
            frequency_hz=float(frequency),
            damping_ratio=max(SECOND_MODE_DAMPING_RATIOS),
            modal_mass_kg=1.0,
        )
        for frequency in np.geomspace(lowest, highest, MODE_LIMIT_FREQUENCIES)
    )


def start_term(
    effect: str,
    impacts: Sequence[ConditionedImpact],
    where: Where,
    rig: Rig,
    ranges: Mapping[str, tuple[float, float]] | None = None,
) -> ModelTerm:
    """One candidate term at the size its signature points at (not the second mode's).

    Each is a rough estimate from the measured-minus-model signatures, clipped into the term's
    bounds (ranges where given, else its declared ones); the screen and the refit do the rest.
    """
    cls = MODEL_TERMS[effect]
    lower, upper = cls.bounds(ranges)

    def clipped(*values: float) -> ModelTerm:
        return cls.from_vector(np.clip(values, lower, upper))

    pairs = [
        (m, s)
        for m, s in zip(where.measured, where.model, strict=True)
        if m.half_cycles >= 3 and s.half_cycles >= 3
    ]

    def difference(attribute: str) -> float:
        values = [getattr(m, attribute) - getattr(s, attribute) for m, s in pairs]
        values = [v for v in values if math.isfinite(v)]
        return float(np.median(values)) if values else math.nan

    stiffness, mass = rig.stiffness_n_per_m, rig.mass_kg
    if effect == 'viscous_damping':
        slopes = [
            (m.peak_map_slope, s.peak_map_slope)
            for m, s in pairs
            if m.peak_map_slope > 0 and s.peak_map_slope > 0
        ]
        zeta = (
            float(np.median([math.log(s / m) / math.pi for m, s in slopes])) if slopes else math.nan
        )
        added = 2.0 * zeta * math.sqrt(stiffness * mass)
        return clipped(added if math.isfinite(added) and added > 0.01 else 0.2)
    if effect == 'asymmetric_friction':
        # Centres alternate between -mu+ N / k and +mu- N / k: their mean is -d N / (2k).
        shift = difference('centre_m')
        d = -2.0 * stiffness * shift / rig.normal_force_n if math.isfinite(shift) else 0.0
        return clipped(d if abs(d) > 1e-3 else 5e-3)
    if effect == 'cubic_stiffness':
        # Duffing: half period T0 (1 - 3 k3 A^2 / (8 k)), so dT / d(A^2) = -3 k3 T0 / (8 k).
        slope = difference('half_period_amplitude_slope_s_per_m2')
        half_period = math.pi * math.sqrt(mass / stiffness)
        k3 = -8.0 * stiffness * slope / (3.0 * half_period) if math.isfinite(slope) else 0.0
        return clipped(k3 if abs(k3) > 1e3 else 1e4)
    if effect == 'velocity_offset':
        offset = where.rest_velocity_m_s
        return clipped(offset if math.isfinite(offset) else 0.0)
    if effect == 'sensor_delay':
        delay = where.phase_delay_s
        return clipped(
            delay if math.isfinite(delay) and delay > 0.0 else 1.0 / impacts[0].sample_rate_hz
        )
    raise BadInputError(f'no start rule for {effect!r}')
