"""Per-session results kept on disk, keyed by what they were computed from.

A key is the BLAKE2b hash of the session's bytes (every file it reads, and its mapping), its
options (how it is read, analysed, fitted with which rig, diagnosed or not), and the source of
the fmm_ros package that computes it.
So a campaign run again after a crash, or with sessions added, recomputes only what is new or
changed; relabelling a session (its conditions, its id) reuses its result, and any change to
the code or the options recomputes everything. Entries are JSON files written atomically
(a temporary file renamed into place), so a crash mid-write leaves no half entry; an entry
that cannot be read is treated as absent.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import tempfile
from pathlib import Path

from fmm_ros.campaign.session import (
    SessionOutcome,
    SessionSpec,
    options_dict,
    session_files,
    session_options,
)
from fmm_ros.workflows.session import SessionOptions

_CHUNK_BYTES = 1 << 20
CACHE_FORMAT = 1
"""Bumped when SessionOutcome's stored form changes."""


def session_key(spec: SessionSpec, options: SessionOptions) -> str:
    """The cache key of a session under these options (reads every byte of its files)."""
    digest = hashlib.blake2b(digest_size=20)
    header = {
        'format': CACHE_FORMAT,
        'code': code_hash(),
        'options': options_dict(session_options(spec, options)),  # its rig and mapping too
    }
    digest.update(json.dumps(header, sort_keys=True, default=repr).encode())
    files = [*session_files(spec), *([spec.mapping] if spec.mapping else [])]
    for path in files:
        for member in _members(path):
            digest.update(member.relative_to(path).as_posix().encode() + b'\0')
            with open(member, 'rb') as stream:
                while chunk := stream.read(_CHUNK_BYTES):
                    digest.update(chunk)
            digest.update(b'\0')
    return digest.hexdigest()


def _members(path: Path) -> list[Path]:
    """A file, or every file under a directory (a bag) in a fixed order."""
    if path.is_dir():
        return sorted(member for member in path.rglob('*') if member.is_file())
    return [path]


@functools.cache
def code_hash() -> str:
    """Hash of the fmm_ros package's Python source (this process's copy of it)."""
    package = Path(__file__).resolve().parents[1]
    digest = hashlib.blake2b(digest_size=16)
    for path in sorted(package.rglob('*.py')):
        digest.update(path.relative_to(package).as_posix().encode() + b'\0')
        digest.update(path.read_bytes())
    return digest.hexdigest()


class ResultCache:
    """A directory of session results, one `<key>.json` each."""

    def __init__(self, directory: str | Path) -> None:
        self.directory = Path(directory)

    def path(self, key: str) -> Path:
        """Where the entry of a key lives."""
        return self.directory / f'{key}.json'

    def get(self, key: str) -> SessionOutcome | None:
        """The stored result, marked cached; None when absent or unreadable."""
        try:
            data = json.loads(self.path(key).read_text(encoding='utf-8'))
            return dataclasses.replace(SessionOutcome.from_dict(data), cached=True)
        except (OSError, ValueError):
            return None

    def put(self, key: str, result: SessionOutcome) -> None:
        """Store a result under its key, atomically."""
        self.directory.mkdir(parents=True, exist_ok=True)
        text = json.dumps(dataclasses.replace(result, cached=False).to_dict())
        handle, temporary = tempfile.mkstemp(dir=self.directory, prefix='.', suffix='.tmp')
        try:
            with os.fdopen(handle, 'w', encoding='utf-8') as stream:
                stream.write(text)
            os.replace(temporary, self.path(key))
        except BaseException:
            Path(temporary).unlink(missing_ok=True)
            raise
