"""The hammer alone, from lab files: every hit of each file's force channel, judged.

`fmm analyze --force-only` reads only the force (and the time base) of each file, with the
channel mapping semantics of every other input (`fmm_ros.io.labfiles`), and lists its hits
(`fmm_ros.core.signal.hammer`). A file without a hit is a result (zero hits, said in words),
not an error: a recording of a session where nobody hit is what it is.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fmm_ros.core.signal.config import FLAGS
from fmm_ros.core.signal.hammer import Hit, hammer_hits
from fmm_ros.errors import BadInputError
from fmm_ros.io import sniff
from fmm_ros.io.labfiles import read_lab_file
from fmm_ros.workflows.inputs import InputOptions


@dataclass(frozen=True)
class FileHits:
    """One file's hits, its rate and how it was read."""

    path: Path
    sample_rate_hz: float
    hits: list[Hit]
    notes: list[str]
    peak_force_n: float
    """The largest force of the record (says how far from the trigger a hitless file was)."""
    trigger_level_n: float

    @property
    def verdict(self) -> str:
        """One line: how many hits, how many flagged; or why there is none."""
        if not self.hits:
            return (
                f'{self.path.name}: no hit (the force never reaches the trigger level '
                f'{self.trigger_level_n:g} N; its peak is {self.peak_force_n:.4g} N)'
            )
        flagged = sum(bool(hit.flags) for hit in self.hits)
        return (
            f'{self.path.name}: {len(self.hits)} hit(s) at {self.sample_rate_hz:g} Hz, '
            f'{flagged} flagged'
        )


def read_hammer_hits(
    paths: Sequence[str | Path], options: InputOptions, reject_flags: tuple[str, ...] = FLAGS
) -> list[FileHits]:
    """Each lab file's hits (the force channel alone; bags are refused by name).

    reject_flags: the flags that reject a hit (`AnalysisConfig.reject_flags`).
    """
    found = []
    for path in map(Path, paths):
        if sniff.file_kind(path) == sniff.BAG:
            raise BadInputError(
                f'{path} is a bag: --force-only reads lab files (fmm analyze BAG lists its '
                'impacts with their flags)'
            )
        recording = read_lab_file(path, options.mapping, options.text_format, force_only=True)
        full_scale = options.ranges.force_full_scale_n or recording.full_scale_force_n
        force = recording.force_n
        found.append(
            FileHits(
                path,
                recording.sample_rate_hz,
                hammer_hits(
                    force,
                    recording.sample_rate_hz,
                    options.capture,
                    force_full_scale_n=full_scale,
                    reject_flags=reject_flags,
                ),
                recording.report,
                float(np.nanmax(force)) if np.isfinite(force).any() else float('nan'),
                options.capture.trigger_level_n,
            )
        )
    return found
