"""From force and velocity samples to impacts, flags, impulses, FRFs, level averages, linearity.

`records` (the `ImpactRecord` type), `capture` (the trigger rule, streaming capture and quality
flags), `quality` (the signs of damaged samples those flags use), `frf` (scipy.signal-style
functions), `analysis` (per impact and per level, and which impacts a fit takes),
`history` (the recent past of both streams, for cutting records by sample index).
"""

from fmm_ros.core.signal.analysis import (
    AnalysisConfig,
    ImpactResult,
    ImpactSelection,
    LevelSummary,
    NominalLevel,
    SelectionError,
    Summary,
    analyze_impact,
    select_impacts,
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
    'ImpactSelection',
    'LevelSummary',
    'NominalLevel',
    'SampleHistory',
    'SelectionError',
    'Summary',
    'analyze_impact',
    'capture_impacts',
    'find_triggers',
    'quality_flags',
    'select_impacts',
    'summarize',
]
