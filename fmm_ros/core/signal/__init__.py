"""From force and velocity samples to impacts, flags, impulses, FRFs, level averages, linearity.

`records` (the `ImpactRecord` type), `capture` (the trigger rule, streaming capture and quality
flags), `frf` (scipy.signal-style functions), `analysis` (per impact and per level),
`history` (the recent past of both streams, for cutting records by sample index).
"""

from fmm_ros.core.signal.analysis import (
    AnalysisConfig,
    ImpactResult,
    LevelSummary,
    NominalLevel,
    Summary,
    analyze_impact,
    summarize,
)
from fmm_ros.core.signal.capture import (
    DEFAULT_CAPTURE,
    FLAGS,
    CaptureConfig,
    ImpactCapture,
    capture_impacts,
    find_triggers,
    quality_flags,
)
from fmm_ros.core.signal.history import SampleHistory
from fmm_ros.core.signal.records import ImpactRecord

__all__ = [
    'DEFAULT_CAPTURE',
    'FLAGS',
    'AnalysisConfig',
    'CaptureConfig',
    'ImpactCapture',
    'ImpactRecord',
    'ImpactResult',
    'LevelSummary',
    'NominalLevel',
    'SampleHistory',
    'Summary',
    'analyze_impact',
    'capture_impacts',
    'find_triggers',
    'quality_flags',
    'summarize',
]
