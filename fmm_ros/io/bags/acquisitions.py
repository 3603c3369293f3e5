"""Where one acquisition ends and the next begins in a bag joined from several recordings.

`fmm import a.csv b.csv c.csv` writes the three files on one sample index, one after the
other. Each file is its own acquisition: the samples before its first one and after its last
were never taken, so an impact record near its end must end with the file, not run into the
next file's samples or be padded with missing (NaN) ones. The bag says so explicitly: its
metadata.yaml `custom_data` holds, under `ACQUISITIONS_KEY`, the list of acquisitions (first
sample index, sample count, source) as JSON, and replay ends the capture's acquisition at
each boundary (`ImpactCapture.end_acquisition`). A bag without the key is one acquisition.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import yaml

from fmm_ros.errors import BadInputError
from fmm_ros.io.bags.metadata import load_yaml

if TYPE_CHECKING:  # the writer (and the mcap library's) only where a joined bag is written
    from fmm_ros.io.bags.writer import BagWriter

ACQUISITIONS_KEY = 'fmm.acquisitions'


@dataclass(frozen=True)
class Acquisition:
    """One recording of a joined bag: its samples' first index and count, and its origin."""

    first_sample_index: int
    samples: int
    source: str = ''

    @property
    def stop_index(self) -> int:
        """Index just past its last sample."""
        return self.first_sample_index + self.samples


def write_acquisitions(writer: BagWriter, acquisitions: list[Acquisition]) -> None:
    """Record the acquisitions of a joined bag in its metadata (written on close)."""
    writer.set_custom_data(
        ACQUISITIONS_KEY, json.dumps([asdict(acquisition) for acquisition in acquisitions])
    )


def read_acquisitions(bag: str | Path) -> tuple[Acquisition, ...]:
    """The acquisitions a bag's metadata.yaml lists, in index order; () when it lists none.

    Only a bag directory has metadata.yaml (a lone storage file or a crashed recording is read
    as one acquisition). A damaged metadata.yaml or a malformed entry is a ValueError naming
    the bag.
    """
    metadata = Path(bag) / 'metadata.yaml'
    if not metadata.is_file():
        return ()
    try:
        info = load_yaml(metadata.read_bytes().decode('utf-8')) or {}
        text = ((info.get('rosbag2_bagfile_information') or {}).get('custom_data') or {}).get(
            ACQUISITIONS_KEY
        )
        if text is None:
            return ()
        entries = json.loads(text)
        acquisitions = tuple(
            Acquisition(int(e['first_sample_index']), int(e['samples']), str(e.get('source', '')))
            for e in entries
        )
    except (yaml.YAMLError, ValueError, AttributeError, KeyError, TypeError) as error:
        raise BadInputError(
            f'{bag}: unreadable {ACQUISITIONS_KEY} in metadata.yaml: {error}'
        ) from None
    return tuple(sorted(acquisitions, key=lambda a: a.first_sample_index))
