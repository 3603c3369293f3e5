"""A simulated impact-test session: when each hammer hit lands, how hard, and the force streams.

The paper's protocol (Sec. 4): hits at three nominal levels, accepted within +-50 N, ten per
level, each followed by a 33 s record. `session_schedule` draws such a session (hand scatter
on the peak, the tip's contact duration for that peak, a little skew in the pulse shape, a
sub-sample start) from a seed; `HammerStream` renders any sample range of it as the force
the hammer applies and the force its sensor reports (applied + Gaussian noise). Rendering
depends only on the sample indices asked for, so any batch size gives the same streams.
"""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fmm_ros.core._checks import require_non_negative, require_positive
from fmm_ros.errors import BadInputError
from fmm_ros.sim.excitation import hammer_pulse, tip_contact_duration_s


@dataclass(frozen=True)
class ScheduledHit:
    """One hit of a session: where it starts (fractional sample index) and its pulse."""

    level: str
    start_index: float
    peak_force_n: float
    contact_duration_s: float
    rise_fraction: float


def session_schedule(
    levels: Sequence[tuple[str, float]],
    hits_per_level: int,
    *,
    sample_rate_hz: float,
    spacing_s: float,
    first_hit_s: float,
    rng: np.random.Generator | int,
    spread_std_n: float = 20.0,
    contact_scale: float = 1.0,
) -> tuple[ScheduledHit, ...]:
    """Hits level by level (as the paper's operator worked), `spacing_s` apart.

    levels: (name, nominal peak force [N]) pairs. Each hit's peak is the nominal one plus
    normal scatter of `spread_std_n` (a hand-swung hammer); its contact duration follows the
    paper's tip (times `contact_scale`: below 1 a harder tip, sharper hits); its rise
    fraction varies around 0.45; its start falls between samples.
    """
    require_positive('sample_rate_hz', sample_rate_hz)
    require_positive('spacing_s', spacing_s)
    require_non_negative('first_hit_s', first_hit_s)
    require_non_negative('spread_std_n', spread_std_n)
    require_positive('contact_scale', contact_scale)
    if hits_per_level < 1:
        raise BadInputError(f'hits_per_level must be at least 1, got {hits_per_level}')
    if not levels:
        raise BadInputError('a session needs at least one force level')
    rng = np.random.default_rng(rng)
    hits = []
    for name, nominal_n in levels:
        require_positive(f'nominal peak force of level {name!r}', nominal_n)
        for _ in range(hits_per_level):
            peak = max(float(nominal_n + rng.normal(0.0, spread_std_n)), 1.0)
            start_s = first_hit_s + len(hits) * spacing_s + rng.uniform(0.0, 1.0) / sample_rate_hz
            hits.append(
                ScheduledHit(
                    level=name,
                    start_index=start_s * sample_rate_hz,
                    peak_force_n=peak,
                    contact_duration_s=contact_scale * tip_contact_duration_s(peak),
                    rise_fraction=float(rng.uniform(0.40, 0.50)),
                )
            )
    return tuple(hits)


class HammerStream:
    """Renders a schedule as applied and measured force for any [first, first + n) samples."""

    def __init__(
        self,
        schedule: Sequence[ScheduledHit],
        sample_rate_hz: float,
        *,
        noise_std_n: float,
        seed: int,
    ) -> None:
        require_positive('sample_rate_hz', sample_rate_hz)
        require_non_negative('noise_std_n', noise_std_n)
        self.sample_rate_hz = sample_rate_hz
        self.noise_std_n = noise_std_n
        self._seed = seed
        # Each pulse rendered once, on the integer samples from floor(start_index) on.
        self._pulses = []
        for hit in schedule:
            first = int(np.floor(hit.start_index))
            offset_s = (hit.start_index - first) / sample_rate_hz
            span_s = offset_s + hit.contact_duration_s + 2.0 / sample_rate_hz
            pulse = hammer_pulse(
                hit.peak_force_n,
                hit.contact_duration_s,
                sample_rate_hz,
                span_s,
                start_s=offset_s,
                rise_fraction=hit.rise_fraction,
            )
            self._pulses.append((first, pulse))
        self.end_index = max((first + pulse.size for first, pulse in self._pulses), default=0)

    def hits_started_before(self, index: int) -> int:
        """How many hits begin before sample `index` (hits sent once it has been published)."""
        return sum(1 for first, _ in self._pulses if first < index)

    def applied(self, first_index: int, out: np.ndarray) -> np.ndarray:
        """Fill out with the force the hammer applies over [first_index, first_index + len)."""
        out[:] = 0.0
        stop = first_index + out.size
        for first, pulse in self._pulses:
            low, high = max(first, first_index), min(first + pulse.size, stop)
            if low < high:
                out[low - first_index : high - first_index] += pulse[low - first : high - first]
        return out

    def measured(self, applied_n: np.ndarray, first_index: int, out: np.ndarray) -> np.ndarray:
        """Fill out with what the force sensor reports: applied force plus white noise [N]."""
        np.copyto(out, applied_n)
        return add_indexed_noise(out, first_index, self.noise_std_n, self._seed)


NOISE_BLOCK_SAMPLES = 4096


def add_indexed_noise(out: np.ndarray, first_index: int, std: float, seed: int) -> np.ndarray:
    """Add white Gaussian noise of `std` to out, which holds samples [first_index, ...).

    The noise of sample i comes from a generator keyed by (seed, i // NOISE_BLOCK_SAMPLES), so
    it depends on the sample index alone, never on how a stream is cut into batches: a
    simulated sensor gives the same record whatever its batch size or rate factor.
    """
    if std == 0.0 or out.size == 0:
        return out
    stop = first_index + out.size
    block = NOISE_BLOCK_SAMPLES
    for start in range(first_index - first_index % block, stop, block):
        noise = np.random.default_rng((seed, start // block)).normal(0.0, std, block)
        low, high = max(start, first_index), min(start + block, stop)
        out[low - first_index : high - first_index] += noise[low - start : high - start]
    return out
