"""Any response sensor: velocity, acceleration or displacement, and the velocity of each.

Most impact tests measure the response with an accelerometer; the FMM's vibrometer measures
velocity; a capacitive probe or an encoder measures displacement. The analysis works with two
views of one measurement:

- spectra: the DFT of the measured response becomes the velocity spectrum exactly, bin by bin
  (`velocity_spectrum`: A / (i omega), or i omega X), so mobility, accelerance and receptance
  (and H1, H2, coherence, which a per-bin factor passes through unchanged) are the sensor's
  own FRF times a known factor, never the FRF of a numerically integrated signal;
- time: the fit, the natural frequency and the diagnosis take a velocity record, so an
  acceleration is integrated (`velocity_from_response`: the trapezoid rule from rest, the
  offset before the hit removed first) and a displacement differentiated (central
  differences). What the integration leaves (a sensor offset that creeps after the hit) is a
  slow drift of the velocity, which the fit's drift basis (`fmm_ros.core.identify.chain`)
  estimates and removes as it does a vibrometer's.

The velocity made from an accelerometer is not white: its noise is the integral of the
sensor's white noise, a random walk whose spectrum falls as 1/f^2 (the drift handling takes
its slowest part). The diagnosis judges residuals against white velocity noise, so such a
record's noise is described to it by `converted_noise`: the white velocity noise with the same
spectral density at the rig's natural frequency, where its motion and every candidate
effect's signature lie, and the smaller variance it leaves in a residual once the drift is
taken off (a displacement, differentiated, likewise: its noise is blue).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from fmm_ros.constants import RESPONSE_CHANNELS
from fmm_ros.core.signal.capture import (
    DEFAULT_CAPTURE,
    CaptureConfig,
    contact_start_index,
    find_triggers,
)
from fmm_ros.core.signal.quality import white_noise_std
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.errors import BadInputError

RESPONSE_QUANTITIES: tuple[str, ...] = tuple(channel.quantity for channel in RESPONSE_CHANNELS)
"""What a response sensor may measure; each has its SI unit in `fmm_ros.units`."""
VELOCITY, ACCELERATION, DISPLACEMENT = RESPONSE_QUANTITIES

FRF_FORMS: dict[str, str] = {
    'accelerance': ACCELERATION,
    'mobility': VELOCITY,
    'receptance': DISPLACEMENT,
}
"""The three FRF forms and the quantity over force each is."""

_POWER = {DISPLACEMENT: -1, VELOCITY: 0, ACCELERATION: 1}
"""Each quantity is (i omega)^power times the velocity spectrum."""


def checked_quantity(quantity: str) -> str:
    """The quantity if it is a response quantity; BadInputError naming the known ones."""
    if quantity not in RESPONSE_QUANTITIES:
        raise BadInputError(
            f'a response channel of unknown kind {quantity!r}: a response sensor measures '
            f'{", ".join(RESPONSE_QUANTITIES)}'
        )
    return quantity


def convert_spectrum(
    spectrum: np.ndarray, frequency_hz: np.ndarray, source: str, target: str
) -> np.ndarray:
    """The spectrum of quantity `target` from that of `source`, bin by bin (0 at DC).

    Multiplying by i omega differentiates, dividing integrates (numpy's DFT sign, see
    `fmm_ros.core.signal.frf`). DC carries no integrated quantity (its constant is not
    measured), so a division leaves 0 there, as receptance from mobility does.
    """
    power = _POWER[checked_quantity(target)] - _POWER[checked_quantity(source)]
    spectrum = np.asarray(spectrum)
    if power == 0:
        return spectrum
    factor = (2j * np.pi * np.asarray(frequency_hz, dtype=float)) ** abs(power)
    if power > 0:
        return spectrum * factor
    out = np.zeros(np.broadcast(spectrum, factor).shape, dtype=complex)
    np.divide(spectrum, factor, out=out, where=factor != 0)
    return out


def velocity_from_response(
    samples: np.ndarray, quantity: str, sample_rate_hz: float, rest_samples: int
) -> np.ndarray:
    """The velocity [m/s] of a response record in SI units of `quantity`.

    rest_samples: how many samples at the start are before the hit (the rig at rest): the
    acceleration's median there is its sensor offset, removed before integrating, and the
    velocity starts from 0. A displacement is differentiated by central differences (one-sided
    at the ends), whose error is a phase-free low-pass of (omega T)^2 / 6: 0.02 % at a tenth of
    the Nyquist frequency.
    """
    values = np.asarray(samples, dtype=float)
    if checked_quantity(quantity) == VELOCITY:
        return values
    if quantity == DISPLACEMENT:
        return np.gradient(values, 1.0 / sample_rate_hz) if values.size > 1 else values * 0
    before = values[: max(0, rest_samples)]
    before = before[np.isfinite(before)]
    offset = float(np.median(before)) if before.size else 0.0
    steps = 0.5 * (values[1:] + values[:-1] - 2 * offset) / sample_rate_hz
    return np.concatenate(([0.0], np.cumsum(steps)))


@dataclasses.dataclass(frozen=True)
class ConvertedNoise:
    """How a sensor's white noise looks in the velocity made from it [m/s].

    For a velocity sensor both are its white-noise deviation. Integrated or differentiated,
    the noise is coloured, and the one number a white-noise judgement takes splits in two.
    """

    band_std_m_s: float
    """The white velocity noise of equal spectral density at the band's frequency: the
    yardstick of evidence (chi^2) for signatures in that band."""
    residual_std_m_s: float
    """The deviation the noise leaves in a residual sample by sample: what a misfit's mean
    square holds beyond the model's error."""


DRIFT_RESIDUAL_FRACTION = 0.1
"""A random walk of variance q per second, less a drift linear between knots L seconds apart
fitted by least squares, keeps q L times this on average (0.09-0.11 measured, records of
1.5 to 8 knot spans; a straight line over a span L keeps 1/15, a line through its ends 1/6)."""


def converted_noise(
    samples: np.ndarray,
    quantity: str,
    sample_rate_hz: float,
    frequency_hz: float,
    drift_knot_s: float,
) -> ConvertedNoise:
    """The noise of the velocity made from a `quantity` sensor's samples (`ConvertedNoise`).

    The sensor's white noise sigma (`white_noise_std` of its samples, SI units of quantity):

    - integrated (acceleration): a random walk, of spectral density 2 sigma^2 / f_s /
      (2 pi f)^2; white velocity noise of deviation s has 2 s^2 / f_s, so s = sigma /
      (2 pi f) at the band's frequency f (stronger below it, weaker above). Its variance
      grows without bound, but the drift handling (knots drift_knot_s apart) takes the walk's
      slow part, and leaves sigma^2 / f_s x drift_knot_s x DRIFT_RESIDUAL_FRACTION.
    - differentiated (displacement, central differences): s = sigma 2 pi f at f, and
      sigma^2 f_s^2 / 2 sample by sample.
    """
    sigma = white_noise_std(samples)
    omega = 2.0 * np.pi * frequency_hz
    if checked_quantity(quantity) == VELOCITY:
        return ConvertedNoise(sigma, sigma)
    if quantity == ACCELERATION:
        walk = sigma * np.sqrt(drift_knot_s * DRIFT_RESIDUAL_FRACTION / sample_rate_hz)
        return ConvertedNoise(float(sigma / omega), float(walk))
    return ConvertedNoise(float(sigma * omega), float(sigma * sample_rate_hz / np.sqrt(2.0)))


def as_measured(
    record: ImpactRecord, quantity: str, capture: CaptureConfig = DEFAULT_CAPTURE
) -> ImpactRecord:
    """A record whose velocity_m_s slot holds the samples of a `quantity` sensor, made whole.

    The capture and the lab-file readers carry the response channel where a velocity goes;
    for an acceleration or displacement this moves the samples (and the range) to
    `response` and puts their velocity (`velocity_from_response`) in velocity_m_s, its rest
    being the samples before the pulse that fires the trigger (all of them without one).
    """
    if checked_quantity(quantity) == VELOCITY:
        return record
    force = record.force_n
    trigger = record.trigger_offset
    if trigger is None:
        triggers = find_triggers(force, record.sample_rate_hz, capture)
        trigger = int(triggers[0]) if triggers.size else None
    rest = force.size if trigger is None else contact_start_index(force, trigger, capture)
    return dataclasses.replace(
        record,
        velocity_m_s=velocity_from_response(
            record.velocity_m_s, quantity, record.sample_rate_hz, rest
        ),
        velocity_full_scale_m_s=0.0,
        response_quantity=quantity,
        response=record.velocity_m_s,
        response_full_scale=record.velocity_full_scale_m_s,
    )
