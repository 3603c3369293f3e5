"""The per-impact CSV file consumers read: a header `time_s,force_n,velocity_m_s`, one row a sample.

Written here independently of the product's writer. Times are relative to the record's first
sample; a record with dropped samples keeps its true times, so the gap shows in the time
column. Non-finite samples are written as `nan` / `inf` / `-inf` (a damaged file stays damaged).
"""

from pathlib import Path

import numpy as np

from worlds.lab import LabRecord

HEADER = 'time_s,force_n,velocity_m_s'


def write_record_csv(path: str | Path, record: LabRecord) -> Path:
    """Write `record` to `path` (times to 1 ns, samples at full double precision)."""
    path = Path(path)
    time_s = record.time_s - record.time_s[0]
    np.savetxt(
        path,
        np.column_stack((time_s, record.force_n, record.velocity_m_s)),
        delimiter=',',
        header=HEADER,
        comments='',
        fmt=('%.9f', '%.17g', '%.17g'),
    )
    return path
