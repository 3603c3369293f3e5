"""What kind of file a path is, from its content: a bag, or which lab file format.

Labs name files as they like (`trial 3.dat`, `hit.MAT`, an export without a suffix), so the
readers are chosen by the bytes a format starts with, not by the extension: MCAP and SQLite
bags, NI TDMS, NumPy .npz (a zip archive), MATLAB v7.3 (HDF5, after a 512-byte text block),
MATLAB v5/v7 (a text header naming itself), and delimited text. Only MATLAB v4, which has no
signature, is known by its `.mat` suffix alone.
"""

import zipfile
from pathlib import Path

from fmm_ros.errors import BadInputError

BAG = 'bag'
CSV = 'CSV'
NPZ = 'NPZ'
MATLAB = 'MATLAB'
MATLAB_73 = 'MATLAB v7.3'
TDMS = 'TDMS'
KINDS = (BAG, CSV, NPZ, MATLAB, MATLAB_73, TDMS)

MCAP_MAGIC = b'\x89MCAP0\r\n'
SQLITE_MAGIC = b'SQLite format 3\x00'
TDMS_MAGICS = (b'TDSm', b'TDSh')  # a segment's lead-in; an index file's
ZIP_MAGIC = b'PK\x03\x04'
HDF5_MAGIC = b'\x89HDF\r\n\x1a\n'
# HDF5 puts its signature at 0 or after a user block of 512, 1024, 2048, ... bytes (MATLAB
# v7.3 writes a 512-byte one holding its own text header).
HDF5_OFFSETS = (0, 512, 1024, 2048, 4096)
MATLAB_HEADER = b'MATLAB '  # 'MATLAB 5.0 MAT-file, ...' opens a v5/v7 file's 128-byte header
HEAD_BYTES = 8192
TEXT_BOMS = (b'\xef\xbb\xbf', b'\xff\xfe', b'\xfe\xff')
SUPPORTED = 'delimited text (CSV/TSV/TXT), NumPy .npz, MATLAB .mat (v4-v7.3), NI TDMS or a bag'


def file_kind(path: str | Path) -> str:
    """One of KINDS for a file or directory; ValueError naming it when it is none of them.

    A directory is a bag when it holds metadata.yaml or an .mcap/.db3 file.
    """
    path = Path(path)
    if path.is_dir():
        if (
            (path / 'metadata.yaml').is_file()
            or any(path.glob('*.mcap'))
            or any(path.glob('*.db3'))
        ):
            return BAG
        raise BadInputError(
            f'{path} is a directory but not a bag (no metadata.yaml, .mcap or .db3)'
        )
    if not path.is_file():
        raise FileNotFoundError(f'{path} does not exist')
    with path.open('rb') as stream:
        head = stream.read(HEAD_BYTES)
    if head.startswith(MCAP_MAGIC) or head.startswith(SQLITE_MAGIC):
        return BAG
    if head.startswith(TDMS_MAGICS):
        return TDMS
    if head.startswith(ZIP_MAGIC):
        return _zip_kind(path)
    if any(head[offset : offset + len(HDF5_MAGIC)] == HDF5_MAGIC for offset in HDF5_OFFSETS):
        return MATLAB_73
    if head.startswith(MATLAB_HEADER):
        return MATLAB
    if is_text(head):
        return CSV
    if path.suffix.lower() == '.mat':
        return MATLAB  # v4: no signature
    raise BadInputError(
        f'{path}: unknown format {path.suffix!r} (the file starts with {head[:8]!r}); fmm '
        f'reads {SUPPORTED}'
    )


def _zip_kind(path: Path) -> str:
    """NPZ for a zip of .npy arrays; an Excel workbook or another archive is refused."""
    try:
        with zipfile.ZipFile(path) as archive:
            names = archive.namelist()
    except zipfile.BadZipFile as error:
        raise BadInputError(f'{path}: a damaged zip archive ({error})') from None
    if any(name.endswith('.npy') for name in names):
        return NPZ
    what = (
        'an Excel workbook, which fmm does not read: save it as CSV (File > Save As)'
        if any(name.startswith('xl/') for name in names)
        else 'a zip archive without NumPy arrays'
    )
    raise BadInputError(f'{path}: unknown format {path.suffix!r}: {what}; fmm reads {SUPPORTED}')


def is_text(head: bytes) -> bool:
    """Whether the first bytes of a file look like text: a BOM, or no NUL and few controls."""
    if head.startswith(TEXT_BOMS):
        return True
    if b'\x00' in head:
        return False
    controls = sum(byte < 32 and byte not in b'\t\n\r\x0c' for byte in head)
    return controls <= len(head) // 100
