"""From force and velocity samples to impacts, flags, impulses, FRFs, level averages, linearity.

`config` (the declared settings: capture, stream rules, levels, FRFs; numpy-free), `records`
(the `ImpactRecord` type), `capture` (the trigger rule and streaming capture), `quality` (the
signs of damaged samples and the quality flags they raise), `frf` (scipy.signal-style
functions), `levels` (nominal levels and clustering), `analysis` (per impact and per level,
and which impacts a fit takes), `history` (the recent past of both streams, for cutting
records by sample index).
"""

from fmm_ros._lazy import lazy_exports

_EXPORTS = {
    'AnalysisConfig': 'config',
    'CaptureConfig': 'config',
    'DEFAULT_CAPTURE': 'config',
    'FLAGS': 'config',
    'ImpactCapture': 'capture',
    'ImpactRecord': 'records',
    'ImpactAnalysis': 'analysis',
    'ImpactSelection': 'analysis',
    'LevelSummary': 'analysis',
    'NominalLevel': 'config',
    'SampleHistory': 'history',
    'Summary': 'analysis',
    'analyze_impact': 'analysis',
    'capture_impacts': 'capture',
    'find_triggers': 'capture',
    'quality_flags': 'quality',
    'select_impacts': 'analysis',
    'summarize': 'analysis',
}

__all__ = sorted(_EXPORTS)
__getattr__ = lazy_exports(__name__, _EXPORTS)
