"""Delimited text as labs write it: encoding, delimiter, decimal comma, header and units rows.

A German Excel export is `Zeit;Hammer;Vibrometer` over `s;N;mm/s` over `0,0001;1,5;0,25` in
cp1252; LabVIEW writes tabs; a DAQ tool may put a few lines of settings first. `read_table`
finds all of it, and `TextFormat` states any part instead:

- encoding: a byte-order mark, else UTF-8, else chardet's guess from the lines of the first
  64 kB that are not ASCII (cp1252 and its kin on Windows machines), else Latin-1, which
  decodes any byte;
- delimiter: clevercsv's dialect detection over the first lines, restricted to `,;|`, tab
  and blanks (it scores how consistently rows split into typed cells, so a header-less
  semicolon file full of decimal commas is not taken for comma-separated, as the standard
  library's csv.Sniffer takes it);
- decimal comma: when the delimiter is not a comma and the numbers are written `0,25`;
- rows: the first row whose cells are all numbers starts the data; the first row before it
  with as many cells is the header, and a second such row under it the units row. Rows
  before the header (or the first `skip_rows` rows, when stated) are a preamble; `#` lines
  and blank lines are comments.
"""

from __future__ import annotations

import codecs
import csv
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fmm_ros.errors import BadInputError
from fmm_ros.io.textformat import (
    DELIMITER_NAMES,
    DELIMITERS,
    DETECT,
    TextFormat,
)

SNIFF_LINES = 40
"""Lines (after the preamble) the delimiter and decimal are detected from."""
SNIFF_BYTES = 65_536
"""Bytes an encoding is guessed from."""
BOMS = (
    (codecs.BOM_UTF32_LE, 'utf-32'),  # before UTF-16 LE, whose BOM it starts with
    (codecs.BOM_UTF32_BE, 'utf-32'),
    (codecs.BOM_UTF8, 'utf-8-sig'),
    (codecs.BOM_UTF16_LE, 'utf-16'),
    (codecs.BOM_UTF16_BE, 'utf-16'),
)
_COMMA_NUMBER = re.compile(r'^[-+]?(\d+,\d*|,\d+)([eE][-+]?\d+)?$')
_DOT_NUMBER = re.compile(r'^[-+]?(\d+\.\d*|\.\d+)([eE][-+]?\d+)?$')


@dataclass(frozen=True, eq=False)
class TextTable:
    """A delimited text file read: column names and units, and how it was read."""

    path: Path
    names: tuple[str, ...]
    """Header cells as written, or '0', '1', ... without a header."""
    units: tuple[str | None, ...]
    """Each column's units-row cell, or None without a units row."""
    encoding: str
    delimiter: str
    decimal: str
    data_line: int
    """1-based line number of the first data row."""
    _text: str
    """The file's text."""
    _data_offset: int
    """Where the first data row starts in it."""

    def describe(self) -> str:
        """How the file was read, for an import report: 'semicolon, decimal comma, cp1252'."""
        name = {value: key for key, value in reversed(DELIMITER_NAMES.items())}[self.delimiter]
        parts = [
            f'{name}-delimited',
            'decimal comma' if self.decimal == ',' else '',
            'units row' if any(self.units) else '',
            self.encoding,
            f'data from line {self.data_line}',
        ]
        return ', '.join(part for part in parts if part)

    def values(self) -> np.ndarray:
        """The data rows as a (rows, columns) float64 array; ValueError naming the line.

        The rows go to numpy's parser a piece of the text at a time (`_pieces`), so reading
        takes the text and the array, not a list of every line and two more copies.
        """
        comma = self.decimal == ','
        rows = (
            line
            for _, piece in _pieces(self._text, self._data_offset)
            for line in (piece.replace(',', '.') if comma else piece).splitlines()
        )
        try:
            table = np.loadtxt(
                rows,
                delimiter=None if self.delimiter == ' ' else self.delimiter,
                usecols=range(len(self.names)),
                ndmin=2,
                quotechar='"',
                comments='#',
            )
        except ValueError as error:
            raise BadInputError(
                f'{self.path}: {error} (data rows from line {self.data_line}, read as '
                f'{self.describe()}; state --delimiter, --decimal or --skip-rows if that is '
                'not how the file is laid out)'
            ) from None
        return table


LINE_PIECE = 1 << 16
"""Characters a text is split into lines at a time (see `_pieces`)."""


def _pieces(text: str, offset: int = 0) -> Iterator[tuple[int, str]]:
    r"""(offset, piece) of text from offset on, in pieces of about LINE_PIECE characters.

    Each piece ends just after a '\n' (a '\r' in a file without any) or at the end, so no
    line and no '\r\n' is cut; it is split into lines at C speed, while a 10 MB file is never
    held again as a list of every line.
    """
    size = len(text)
    newline = '\n' if text.find('\n', offset) >= 0 else '\r'  # '\r' alone: old Mac files
    while offset < size:
        end = text.find(newline, min(offset + LINE_PIECE, size - 1))
        end = size if end < 0 else end + 1
        yield offset, text[offset:end]
        offset = end


def _lines(text: str, offset: int = 0) -> Iterator[tuple[int, str]]:
    """(offset, line) of each line from offset on, as `str.splitlines` splits them."""
    for start, piece in _pieces(text, offset):
        for line, with_end in zip(piece.splitlines(), piece.splitlines(True), strict=True):
            yield start, line
            start += len(with_end)


def read_table(path: str | Path, text_format: TextFormat = DETECT) -> TextTable:
    """Read a delimited text file's layout (the values are parsed by `TextTable.values`)."""
    path = Path(path)
    content, encoding = decode_text(path.read_bytes(), text_format.encoding, path)
    body = []  # the lines the layout is found from: up to SNIFF_LINES * 4 of them
    offsets = {}  # line number -> where it starts, for those lines
    for number, (offset, line) in enumerate(_lines(content), 1):
        if number > text_format.skip_rows and _is_data(line):
            body.append((number, line))
            offsets[number] = offset
            if len(body) == SNIFF_LINES * 4:
                break
    if not body:
        raise BadInputError(f'{path} holds no data')
    sample = [line for _, line in body[:SNIFF_LINES]]
    delimiter = text_format.delimiter or _detect_delimiter(sample)
    decimal = text_format.decimal or _detect_decimal(sample, delimiter)
    if decimal == delimiter:
        raise BadInputError(
            f'{path}: the delimiter and the decimal separator cannot both be {decimal!r}'
        )
    rows = [(number, _cells(line, delimiter)) for number, line in body]
    start = next(
        (position for position, (_, cells) in enumerate(rows) if _numeric(cells, decimal)), None
    )
    if start is None:
        raise BadInputError(
            f'{path}: no row of numbers in its first {len(rows)} lines (read with delimiter '
            f'{delimiter!r}, decimal {decimal!r}; state --delimiter, --decimal or --skip-rows)'
        )
    width = len(rows[start][1])
    above = [cells for _, cells in rows[:start] if len(_trimmed(cells)) == width]
    names: list[str] = [str(column) for column in range(width)]
    units: list[str | None] = [None] * width
    if above:
        header = _trimmed(above[0])
        names = [cell or str(column) for column, cell in enumerate(header)]
        if len(set(names)) != len(names):
            raise BadInputError(f'{path}: the header names a column twice: {names}')
        if len(above) > 1:
            units = [cell or None for cell in _trimmed(above[1])]
    data_line = rows[start][0]
    return TextTable(
        path,
        tuple(names),
        tuple(units),
        encoding,
        delimiter,
        decimal,
        data_line,
        content,
        offsets[data_line],
    )


def decode_text(raw: bytes, encoding: str | None, path: Path) -> tuple[str, str]:
    """The file's text and the encoding it was read with (see the module doc)."""
    if encoding:
        try:
            return raw.decode(encoding), encoding
        except UnicodeDecodeError as error:
            raise BadInputError(f'{path}: cannot be read as {encoding}: {error}') from None
    for bom, name in BOMS:
        if raw.startswith(bom):
            return raw.decode(name), name
    try:
        return raw.decode('utf-8'), 'utf-8'
    except UnicodeDecodeError:
        pass
    import chardet  # only for files that are not UTF-8

    # Only the lines with non-ASCII bytes (names, units, remarks): thousands of ASCII numbers
    # around a few umlauts make chardet guess Big5 where the names alone say Windows-1252.
    words = b'\n'.join(line for line in raw[:SNIFF_BYTES].splitlines() if not line.isascii())
    guess = chardet.detect(words).get('encoding')
    if guess:
        try:
            return raw.decode(guess), guess.lower()
        except (UnicodeDecodeError, LookupError):
            pass
    return raw.decode('latin-1'), 'latin-1'


def _detect_delimiter(sample: list[str]) -> str:
    """The delimiter of the sample lines (clevercsv), ' ' for one column or blank-separated."""
    import clevercsv  # ~0.2 s to import: only for text files

    dialect = clevercsv.Detector().detect('\n'.join(sample), delimiters=DELIMITERS)
    if dialect is None or dialect.delimiter not in DELIMITERS:
        return ' '
    return dialect.delimiter


def _detect_decimal(sample: list[str], delimiter: str) -> str:
    """',' when the numbers are written with decimal commas (never with a comma delimiter)."""
    if delimiter == ',':
        return '.'
    cells = [cell for line in sample for cell in _cells(line, delimiter)]
    commas = sum(bool(_COMMA_NUMBER.match(cell)) for cell in cells)
    dots = sum(bool(_DOT_NUMBER.match(cell)) for cell in cells)
    return ',' if commas > dots else '.'


def _is_data(line: str) -> bool:
    """Not blank and not a '#' comment."""
    stripped = line.strip()
    return bool(stripped) and not stripped.startswith('#')


def _cells(line: str, delimiter: str) -> list[str]:
    """A line's cells, stripped (quotes removed)."""
    if delimiter == ' ':
        return line.split()
    return [cell.strip() for cell in next(csv.reader([line], delimiter=delimiter))]


def _trimmed(cells: list[str]) -> list[str]:
    """Cells without the empty ones a trailing delimiter leaves."""
    end = len(cells)
    while end and not cells[end - 1]:
        end -= 1
    return cells[:end]


def _numeric(cells: list[str], decimal: str) -> bool:
    """Whether every cell of a row is a number (with that decimal separator)."""
    cells = _trimmed(cells)
    if not cells:
        return False
    for cell in cells:
        try:
            float(cell.replace(',', '.') if decimal == ',' else cell)
        except ValueError:
            return False
    return True
