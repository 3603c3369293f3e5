"""What a data acquisition chain does to a sensor's signal, for the simulated rig.

A real channel is not the sensor's signal plus white noise: an anti-alias filter shapes it,
mains hum (50 or 60 Hz and harmonics) is picked up, the zero is off and creeps. `ChannelChain`
describes one channel, `ChainStream` applies it to a stream batch by batch (`hammer_sim` to
the measured force, `rig_sim` to the vibrometer's velocity), so the simulated rig produces
data as a DAQ delivers it and the fit's handling of it can be exercised end to end. Like the
sensor noise (`sim.hammer.add_indexed_noise`), everything depends on the sample index only:
the filter carries its state from batch to batch, the hum is a function of the index, the
drift's random steps are keyed by index blocks, so any batching gives the same samples.
"""

import math
from dataclasses import dataclass

import numpy as np

from fmm_ros._lazy import LazyModule
from fmm_ros.core._checks import require_non_negative, require_positive
from fmm_ros.errors import BadInputError
from fmm_ros.sim.hammer import NOISE_BLOCK_SAMPLES

signal = LazyModule('scipy.signal')

HUM_HARMONICS = (1, 2, 3, 5)
"""Mains harmonics a channel picks up: the fundamental at `hum_amplitude`, the others at a
fraction of it (1/2, 1/3, 1/5 of the fundamental's, down with the order, as mains
transformer and rectifier pick-up typically falls)."""


@dataclass(frozen=True)
class ChannelChain:
    """One channel's acquisition, in the channel's unit (N or m/s); zeros: a perfect channel."""

    anti_alias_order: int = 0
    """Butterworth low-pass order (0: no filter)."""
    anti_alias_cutoff_hz: float = 4000.0
    """Its -3 dB frequency [Hz]; below the Nyquist frequency."""
    offset: float = 0.0
    """Constant zero error [unit]."""
    drift_per_sqrt_s: float = 0.0
    """Random-walk drift of the zero: its standard deviation after one second [unit]."""
    hum_amplitude: float = 0.0
    """Amplitude of the mains fundamental [unit]."""
    mains_hz: float = 50.0

    def __post_init__(self) -> None:
        if not 0 <= self.anti_alias_order <= 12:
            raise BadInputError(f'anti_alias_order must be 0 to 12, got {self.anti_alias_order}')
        require_positive('anti_alias_cutoff_hz', self.anti_alias_cutoff_hz)
        require_non_negative('drift_per_sqrt_s', self.drift_per_sqrt_s)
        require_non_negative('hum_amplitude', self.hum_amplitude)
        require_positive('mains_hz', self.mains_hz)

    @property
    def is_ideal(self) -> bool:
        """Whether the chain leaves the signal as it is."""
        return not (
            self.anti_alias_order or self.offset or self.drift_per_sqrt_s or self.hum_amplitude
        )


class ChainStream:
    """Applies a `ChannelChain` to consecutive batches of one channel's samples."""

    def __init__(self, chain: ChannelChain, sample_rate_hz: float, seed: int) -> None:
        require_positive('sample_rate_hz', sample_rate_hz)
        self.chain = chain
        self.sample_rate_hz = sample_rate_hz
        self._seed = seed
        self._sos = None
        if chain.anti_alias_order:
            if not chain.anti_alias_cutoff_hz < 0.5 * sample_rate_hz:
                raise BadInputError(
                    f'the anti-alias cutoff {chain.anti_alias_cutoff_hz:g} Hz is not below '
                    f'the Nyquist frequency {0.5 * sample_rate_hz:g} Hz'
                )
            self._sos = signal.butter(
                chain.anti_alias_order,
                chain.anti_alias_cutoff_hz,
                fs=sample_rate_hz,
                output='sos',
            )
            self._state = np.zeros((self._sos.shape[0], 2))
        phases = np.random.default_rng((seed, 1)).uniform(0.0, 2.0 * np.pi, len(HUM_HARMONICS))
        self._hum = [
            (
                chain.hum_amplitude / order,
                2.0 * np.pi * order * chain.mains_hz / sample_rate_hz,
                phase,
            )
            for order, phase in zip(HUM_HARMONICS, phases, strict=True)
        ]
        self._next_index: int | None = None
        self._drift_block = 0
        self._drift_level = 0.0

    def apply(self, first_index: int, samples: np.ndarray) -> np.ndarray:
        """The chain's output for samples [first_index, ...) of the signal (in place).

        Batches must follow each other (the filter's state runs from one to the next); the
        first may start anywhere.
        """
        if self._next_index is not None and first_index != self._next_index:
            raise BadInputError(
                f'batch {first_index} does not follow the last one (next is {self._next_index}): '
                'the chain runs on consecutive samples'
            )
        if self._sos is not None:
            samples[:], self._state = signal.sosfilt(self._sos, samples, zi=self._state)
        self._next_index = first_index + samples.size
        chain = self.chain
        if chain.offset:
            samples += chain.offset
        if chain.hum_amplitude:
            index = np.arange(first_index, first_index + samples.size, dtype=float)
            for amplitude, step_rad, phase in self._hum:
                samples += amplitude * np.sin(step_rad * index + phase)
        if chain.drift_per_sqrt_s:
            samples += self._drift(first_index, samples.size)
        return samples

    def skip(self, to_index: int) -> None:
        """The samples up to to_index never pass the chain (a gap): the next batch starts there.

        The filter's state carries over (the signal was at rest), the drift walks on.
        """
        if self._next_index is not None and to_index < self._next_index:
            raise BadInputError(f'cannot skip back from {self._next_index} to {to_index}')
        self._next_index = int(to_index)

    def _drift(self, first_index: int, count: int) -> np.ndarray:
        """The random walk at samples [first_index, first_index + count).

        One Gaussian step per NOISE_BLOCK_SAMPLES block, keyed by the block's number, linear
        in between; the level at a block's start is the sum of the steps before it, carried.
        """
        block = NOISE_BLOCK_SAMPLES
        step_std = self.chain.drift_per_sqrt_s * math.sqrt(block / self.sample_rate_hz)
        out = np.empty(count)
        index = first_index
        while index < first_index + count:
            number = index // block
            while self._drift_block < number:
                self._drift_level += self._step(self._drift_block, step_std)
                self._drift_block += 1
            stop = min((number + 1) * block, first_index + count)
            step = self._step(number, step_std)
            fraction = (np.arange(index, stop) - number * block) / block
            out[index - first_index : stop - first_index] = self._drift_level + step * fraction
            index = stop
        return out

    def _step(self, number: int, std: float) -> float:
        return float(np.random.default_rng((self._seed, 2, number)).normal(0.0, std))
