"""Impact records kept on disk, one file each, so a node killed outright holds them again.

The fitter cuts each reported impact's record from its own stream history; a fitter killed
with SIGKILL and respawned has an empty history, and sample batches are VOLATILE (no one
sends them again). So, given a state directory, it writes each record it holds here the
moment it holds it (`<impact_id>.npz`, written to a temporary name and renamed: a kill
mid-write leaves the previous state, never half a file) with what the analyzer said about it,
and its live fit (`<impact_id>.fit.json`); a respawned fitter reads them back at start.

NumPy's npz with `allow_pickle=False`: arrays and one JSON string, nothing executable, so a
state directory someone else can write is no way into the node.
"""

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.errors import DamagedFileError

_SCALARS = (
    'sample_rate_hz',
    'record_start_sample_index',
    'trigger_sample_index',
    'window_samples',
    'force_full_scale_n',
    'velocity_full_scale_m_s',
    'source',
    'interrupted',
    'response_quantity',
    'response_full_scale',
    'truncated_start',
    'acquisition_origin_s',
)


@dataclass(frozen=True)
class StoredImpact:
    """One held impact as stored: what the analyzer said about it, and its record."""

    impact_id: int
    level: str
    accepted: bool
    flags: tuple[str, ...]
    stamp_ns: int
    record: ImpactRecord
    live_fit: tuple[str, float, float] | None = None  # (level, mu, mu_stderr), once fitted


def _atomic_write(path: Path, write) -> None:
    temporary = path.with_name(f'.{path.name}.tmp')
    with open(temporary, 'wb') as handle:
        write(handle)
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(temporary, path)


def save_impact(directory: Path, impact: StoredImpact) -> None:
    """Write one held impact's record and metadata (`<impact_id>.npz`), atomically."""
    record = impact.record
    meta = {
        'impact_id': impact.impact_id,
        'level': impact.level,
        'accepted': impact.accepted,
        'flags': list(impact.flags),
        'stamp_ns': impact.stamp_ns,
        'force_gaps': [list(gap) for gap in record.force_gaps],
        'velocity_gaps': [list(gap) for gap in record.velocity_gaps],
        **{name: getattr(record, name) for name in _SCALARS},
    }
    arrays = {
        'force_n': record.force_n,
        'velocity_m_s': record.velocity_m_s,
        'meta': np.array(json.dumps(meta)),
    }
    if record.response is not None:
        arrays['response'] = record.response
    _atomic_write(directory / f'{impact.impact_id}.npz', lambda handle: np.savez(handle, **arrays))


def save_live_fit(directory: Path, impact_id: int, level: str, mu: float, stderr: float) -> None:
    """Write one impact's live fit (`<impact_id>.fit.json`), atomically."""
    text = json.dumps({'level': level, 'mu': mu, 'mu_stderr': stderr}).encode()
    _atomic_write(directory / f'{impact_id}.fit.json', lambda handle: handle.write(text))


def forget_impact(directory: Path, impact_id: int) -> None:
    """Remove one impact's files (it is no longer held)."""
    for name in (f'{impact_id}.npz', f'{impact_id}.fit.json'):
        (directory / name).unlink(missing_ok=True)


def load_impacts(directory: Path) -> tuple[list[StoredImpact], list[str]]:
    """Every impact stored in directory, oldest trigger first, and the files refused (why).

    A file that cannot be read (damaged, or not one of these) is named and skipped, never
    fatal: the node holds the others.
    """
    stored, refused = [], []
    for path in sorted(directory.glob('*.npz')):
        try:
            stored.append(_load(path))
        except (OSError, ValueError, KeyError, TypeError) as error:
            refused.append(f'{path.name}: {type(error).__name__}: {error}')
    stored.sort(key=lambda impact: (impact.stamp_ns, impact.impact_id))
    return stored, refused


def _load(path: Path) -> StoredImpact:
    with np.load(path, allow_pickle=False) as data:
        meta = json.loads(str(data['meta']))
        response = data['response'].copy() if 'response' in data.files else None
        force, velocity = data['force_n'].copy(), data['velocity_m_s'].copy()
    if force.shape != velocity.shape or force.ndim != 1:
        raise DamagedFileError(f'{path}: force and velocity arrays differ in shape')
    record = ImpactRecord(
        force,
        velocity,
        response=response,
        force_gaps=tuple(tuple(gap) for gap in meta['force_gaps']),
        velocity_gaps=tuple(tuple(gap) for gap in meta['velocity_gaps']),
        **{name: meta[name] for name in _SCALARS},
    )
    fit_path = path.with_name(f'{meta["impact_id"]}.fit.json')
    live_fit = None
    if fit_path.exists():
        fit = json.loads(fit_path.read_text())
        live_fit = (str(fit['level']), float(fit['mu']), float(fit['mu_stderr']))
    return StoredImpact(
        int(meta['impact_id']),
        str(meta['level']),
        bool(meta['accepted']),
        tuple(meta['flags']),
        int(meta['stamp_ns']),
        record,
        live_fit,
    )
