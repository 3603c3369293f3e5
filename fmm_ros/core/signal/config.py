"""The settings of the signal core: the stream's tolerances, the capture, the levels, the FRFs.

Each field is declared once here with its default, unit, help and limits (`core.settings`);
the analyzer's ROS parameters, the `fmm` options and the reference docs are made from these
declarations. numpy-free, so `fmm --help` can show every default without importing numerics.
`capture`, `stream` and `analysis` re-export the classes where their users import them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from fmm_ros.constants import LEVEL_TOLERANCE_N, PAPER_LEVELS
from fmm_ros.core.settings import setting, setting_like
from fmm_ros.errors import BadInputError

UNDETERMINED = 'undetermined'
"""The flag of a hit whose headline number (impulse, f_n or peak |X/F|) came out NaN."""

# Every quality flag, in the order they are reported. All but the last two are properties of
# the record (`quality_flags`); `undetermined` is set by the analysis when a headline number
# is NaN and no other flag explains it (no hit is accepted without one), `out_of_tolerance`
# when impacts are grouped into levels.
FLAGS: tuple[str, ...] = (
    'double_hit',
    'clipped',
    'coarse',
    'saturated',
    'no_response',
    'dropout',
    'gap',
    'interrupted',
    'truncated_start',
    'nan',
    'unsettled',
    'overlap',
    UNDETERMINED,
    'out_of_tolerance',
)


@dataclass(frozen=True)
class StreamRules:
    """The tolerances of the stream's rules, in seconds of signal."""

    max_skew_s: float = setting(
        5.0,
        unit='s',
        help='How far one channel may run ahead of the other before samples count as missing',
        limits=(0.0, 600.0),
    )
    max_gap_s: float = setting(
        10.0,
        unit='s',
        help='Largest jump of the sample index that is a gap or a past batch rather than a '
        "new acquisition, when the batches' clocks cannot tell",
        limits=(0.0, 3600.0),
    )
    clock_tolerance_s: float = setting(
        0.5,
        unit='s',
        help='Acquisition clocks further apart than this belong to different acquisitions',
        limits=(0.0, 3600.0),
    )

    def __post_init__(self) -> None:
        for name in ('max_skew_s', 'max_gap_s', 'clock_tolerance_s'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise BadInputError(f'{name} must be a finite number >= 0, got {value}')

    def same_clock(self, a: float | None, b: float | None) -> bool | None:
        """Whether two acquisition origins [s] are one acquisition's (None: either unknown)."""
        if a is None or b is None:
            return None
        return abs(a - b) <= self.clock_tolerance_s


DEFAULT_RULES = StreamRules()


@dataclass(frozen=True)
class CaptureConfig:
    """How impacts are triggered, how long a record runs, and what counts as rest.

    Every sample is tested against the rest level, so it must clear the vibrometer's noise
    peaks (>= 5 noise standard deviations: 1e-4 m/s noise, as in the paper-scale tests, peaks
    near 4.5e-4) while staying well under the motion that makes an FRF leak (a paper-level hit
    starts at ~0.1 m/s; a record ending at 1 mm/s leaks at the 1 % level). With `end_at_rest`
    the FRF grid stays that of window_s: the analysis zero-pads.
    """

    trigger_level_n: float = setting(
        20.0, unit='N', help='Force that starts an impact', limits=(0.0, 1e5), flag='--trigger-n'
    )
    rearm_level_n: float = setting(
        5.0,
        unit='N',
        help='Force the signal must fall below before the next trigger (re-arm and contact '
        'threshold)',
        limits=(-1e5, 1e5),
        flag='--rearm-n',
    )
    pretrigger_s: float = setting(
        0.010, unit='s', help='Record kept before the trigger', limits=(0.0, 10.0)
    )
    window_s: float = setting(
        33.0,
        unit='s',
        help='Record length, pre-trigger included (33 s in the paper: df = 1/33 Hz)',
        limits=(0.01, 3600.0),
    )
    end_at_rest: bool = setting(
        False, help='End a record early once the rig has rested rest_time_s (off in the paper)'
    )
    rest_velocity_m_s: float = setting(
        1e-3, unit='m/s', help='|velocity| counted as rest', limits=(0.0, 10.0)
    )
    rest_time_s: float = setting(
        0.5, unit='s', help='How long rest must last (> 1 period)', limits=(1e-3, 600.0)
    )
    min_spacing_s: float = setting(
        0.5,
        unit='s',
        help='A pulse closer than this to the trigger is a double hit; a later one is the next '
        'impact',
        limits=(1e-3, 600.0),
    )
    # The stream's tolerances (`StreamRules`), which the capture aligns its channels by.
    max_skew_s: float = setting_like(StreamRules, 'max_skew_s')
    max_gap_s: float = setting_like(StreamRules, 'max_gap_s')
    clock_tolerance_s: float = setting_like(StreamRules, 'clock_tolerance_s')

    def __post_init__(self) -> None:
        if not self.rearm_level_n < self.trigger_level_n:
            raise BadInputError(
                f'rearm_level_n ({self.rearm_level_n} N) must be below '
                f'trigger_level_n ({self.trigger_level_n} N) for hysteresis'
            )
        for name in ('window_s', 'rest_velocity_m_s', 'rest_time_s', 'min_spacing_s'):
            if not getattr(self, name) > 0:
                raise BadInputError(f'{name} must be > 0, got {getattr(self, name)}')
        for name in ('pretrigger_s', 'max_skew_s', 'max_gap_s', 'clock_tolerance_s'):
            if not getattr(self, name) >= 0:
                raise BadInputError(f'{name} must be >= 0, got {getattr(self, name)}')
        if not self.pretrigger_s < self.window_s:
            raise BadInputError(
                f'pretrigger_s ({self.pretrigger_s} s) must be shorter than '
                f'window_s ({self.window_s} s)'
            )

    @property
    def rules(self) -> StreamRules:
        """The stream rules this capture aligns its channels by."""
        return StreamRules(self.max_skew_s, self.max_gap_s, self.clock_tolerance_s)

    def samples(self, sample_rate_hz: float) -> CaptureSamples:
        """The durations of this config as whole sample counts at `sample_rate_hz`."""

        def count(seconds: float) -> int:
            return int(round(seconds * sample_rate_hz))

        result = CaptureSamples(
            pretrigger=count(self.pretrigger_s),
            window=count(self.window_s),
            rest=max(1, count(self.rest_time_s)),
            min_spacing=max(1, count(self.min_spacing_s)),
            max_skew=count(self.max_skew_s),
        )
        if result.window <= result.pretrigger:
            raise BadInputError(
                f'at {sample_rate_hz} Hz the window ({result.window} samples) '
                f'leaves nothing after the pre-trigger ({result.pretrigger})'
            )
        return result


DEFAULT_CAPTURE = CaptureConfig()


@dataclass(frozen=True)
class CaptureSamples:
    """`CaptureConfig` durations in samples at one sample rate."""

    pretrigger: int
    window: int
    rest: int
    min_spacing: int
    max_skew: int


@dataclass(frozen=True)
class NominalLevel:
    """A force level the operator aims for: name, nominal peak force [N] and tolerance [N]."""

    name: str
    peak_force_n: float
    tolerance_n: float = setting(
        LEVEL_TOLERANCE_N,
        unit='N',
        help='Acceptance band around each nominal peak force',
        limits=(0.0, 1e6),
    )


def paper_levels(tolerance_n: float = LEVEL_TOLERANCE_N) -> tuple[NominalLevel, ...]:
    """The paper's three levels (Sec. 4: 450, 1000 and 1450 N) as nominal levels, +-50 N."""
    return tuple(
        NominalLevel(level.name, level.peak_force_n, tolerance_n) for level in PAPER_LEVELS
    )


@dataclass(frozen=True)
class SensorRanges:
    """The sensors' full scales in SI, which the clipped/saturated flags compare peaks with.

    0 for a range not given: as the recording states it, else unknown (nothing is flagged).
    """

    force_full_scale_n: float = setting(
        0.0, unit='N', help='Force sensor range (0: as recorded, or unknown)', limits=(0.0, 1e7)
    )
    velocity_full_scale_m_s: float = setting(
        0.0, unit='m/s', help='Vibrometer range (0: as recorded, or unknown)', limits=(0.0, 1e4)
    )
    acceleration_full_scale_m_s2: float = setting(
        0.0,
        unit='m/s^2',
        help='Accelerometer range (0: as recorded, or unknown)',
        limits=(0.0, 1e7),
    )
    displacement_full_scale_m: float = setting(
        0.0,
        unit='m',
        help='Displacement sensor range (0: as recorded, or unknown)',
        limits=(0.0, 1e3),
    )


@dataclass(frozen=True)
class AnalysisConfig:
    """How records become FRFs and how results are grouped and judged.

    The FMM's mode is at 2.2 Hz and its odd harmonics matter up to ~20 Hz; a 100 Hz band keeps
    results small. The peak band's lower end keeps out the lowest bins, where the rest offset
    friction leaves in the displacement (x_final != 0) makes |mobility / (i omega)| large; its
    upper end is lowered further to where the hammer pulse's spectrum (baseline removed: an
    offset, drift or hum on the force channel excites nothing) has dropped by
    excitation_drop_db (`frf.excitation_bandwidth`). Without windows (the paper's method),
    friction brings the rig to rest inside the record.
    """

    band_limit_hz: float | None = setting(
        100.0,
        unit='Hz',
        help='Highest FRF frequency kept in results',
        limits=(0.1, 1e6),
    )
    peak_band_hz: tuple[float, float] = setting(
        (1.0, 100.0),
        unit='Hz',
        help='Band [low, high] searched for the peak |receptance| (its top raised to a higher '
        'band limit)',
        limits=(0.0, 1e6),
    )
    excitation_drop_db: float = setting(
        20.0,
        unit='dB',
        help='The peak band ends where the force spectrum has dropped by this much',
        limits=(0.0, 200.0),
    )
    force_window_s: float | None = setting(
        None,
        unit='s',
        help='Force window length after the trigger (the pre-contact mean subtracted first)',
        limits=(0.0, 3600.0),
    )
    force_window_taper_s: float = setting(
        0.0, unit='s', help='Half-cosine taper after the force window', limits=(0.0, 3600.0)
    )
    exponential_decay_s: float | None = setting(
        None,
        unit='s',
        help='Exponential window decay time constant, on both channels',
        limits=(0.0, 3600.0),
    )
    levels: tuple[NominalLevel, ...] = setting(
        (), help='Nominal force levels; none: peak forces are clustered (`levels.cluster_levels`)'
    )
    cluster_relative_gap: float = setting(
        0.15,
        help='Relative gap between peak forces that separates two clustered levels',
        limits=(0.0, 10.0),
    )
    reject_flags: tuple[str, ...] = setting(
        FLAGS,
        help='Quality flags that reject an impact from averaging (the others are reported)',
        choices=FLAGS,
    )

    def __post_init__(self) -> None:
        unknown = sorted(set(self.reject_flags) - set(FLAGS))
        if unknown:
            raise BadInputError(
                f'unknown quality flag(s) {", ".join(unknown)}; known: {", ".join(FLAGS)}'
            )
        low, high = self.peak_band_hz
        if not 0 <= low < high:
            raise BadInputError(
                f'peak_band_hz must be (low, high) with 0 <= low < high, got {self.peak_band_hz}'
            )
        if self.band_limit_hz is not None and self.band_limit_hz <= low:
            raise BadInputError(
                f'band_limit_hz ({self.band_limit_hz} Hz) leaves no room for the '
                f'peak band starting at {low} Hz'
            )
        for name in ('force_window_s', 'exponential_decay_s'):
            value = getattr(self, name)
            if value is not None and not value > 0:
                raise BadInputError(f'{name} must be > 0 or None, got {value}')
        names = [level.name for level in self.levels]
        if len(set(names)) != len(names) or '' in names:
            raise BadInputError(f'level names must be unique and non-empty, got {names}')


DEFAULT_ANALYSIS = AnalysisConfig()
