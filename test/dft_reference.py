"""The held-out FRF tests' independent computation: a whole record's DFT with numpy alone.

Written apart from `fmm_ros.core.signal` (no windowing, no trigger, no fit), so a held-out
world's peak |X/F| and f_n are checked against a method the analysis does not share.
"""

import math

import numpy as np

BAND_HZ = (1.0, 50.0)
"""Where both peaks are searched [Hz]."""


def independent_peak(
    force_n: np.ndarray,
    velocity_m_s: np.ndarray,
    rate_hz: float,
    onset_s: float,
    padding: int = 8,
) -> tuple[float, float]:
    """(peak |X/F| [m/N], frequency of the peak |V/P| [Hz]) from the whole record's DFT.

    Offsets off: the mean of each channel before the hit (`onset_s`, the hit's start [s]).
    Receptance = V / (F i omega) bin by bin on the record's own grid; its peak is searched
    over BAND_HZ. f_n is where |V/P| peaks there, P the force pulse alone (1 ms either side of
    where the force exceeds 5 % of its peak, zero elsewhere), the records zero-padded
    `padding`-fold (a short Coulomb decay's peak is broad: the 1/33 Hz grid alone can miss it
    by 6 %). Not |V/F| of the whole force: its 0.2 N of noise over 33 s ripples V/F by a few %
    from bin to bin, which moved the top of a 1.2-cycle ring's broad peak by -0.6 to +11 %
    (`newmark`, `karnopp`).
    """
    before = int(onset_s * rate_hz) - 5
    force = force_n - force_n[:before].mean()
    velocity = velocity_m_s - velocity_m_s[:before].mean()
    frequency = np.fft.rfftfreq(force.size, 1.0 / rate_hz)
    band = (frequency >= BAND_HZ[0]) & (frequency <= BAND_HZ[1])
    receptance = np.fft.rfft(velocity)[band] / (
        np.fft.rfft(force)[band] * 2j * math.pi * frequency[band]
    )
    above = np.flatnonzero(force > 0.05 * force.max())
    margin = int(1e-3 * rate_hz)
    pulse = np.zeros_like(force)
    low, high = above[0] - margin, above[-1] + margin + 1
    pulse[low:high] = force[low:high]
    n = padding * force.size
    padded = np.fft.rfftfreq(n, 1.0 / rate_hz)
    inside = (padded >= BAND_HZ[0]) & (padded <= BAND_HZ[1])
    ratio = np.abs(np.fft.rfft(velocity, n)[inside] / np.fft.rfft(pulse, n)[inside])
    return float(np.abs(receptance).max()), float(padded[inside][np.argmax(ratio)])
