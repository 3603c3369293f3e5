"""The words a diagnosis answers in: the candidate effects, `none` and `unexplained`.

Declared apart from the workflow (which needs the numerics) so the `fmm diagnose` options, the
message fields and the docs can name them without importing it.
"""

from fmm_ros.constants import MU_DRIFT
from fmm_ros.core.physics.terms import MODEL_TERMS

EFFECTS: tuple[str, ...] = (*MODEL_TERMS, MU_DRIFT)
"""Candidate effects: the model terms by name, and mu drifting from hit to hit."""

NONE = 'none'
"""The verdict when the base model explains the records."""

UNEXPLAINED = 'unexplained'
"""The verdict when a structured misfit remains that no candidate explains."""

VOCABULARY: tuple[str, ...] = (*EFFECTS, NONE, UNEXPLAINED)
"""Every word a diagnosis may answer with."""
