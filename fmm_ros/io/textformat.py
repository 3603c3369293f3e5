"""How a delimited text file is laid out: what a user can state instead of detection.

`TextFormat` (delimiter, decimal separator, rows before the header, encoding) and the names a
command line gives them. Kept apart from the reader (`textfiles`), which needs numpy, so the
`fmm` options can be declared without it.
"""

from __future__ import annotations

import codecs
from dataclasses import dataclass

from fmm_ros.core.settings import setting
from fmm_ros.errors import BadInputError

DELIMITERS = (',', ';', '\t', ' ', '|')
"""Delimiters detected or accepted; ' ' stands for any run of blanks."""
DELIMITER_NAMES = {
    'comma': ',',
    'semicolon': ';',
    'tab': '\t',
    'space': ' ',
    'whitespace': ' ',
    'pipe': '|',
}
DECIMALS = ('.', ',')


@dataclass(frozen=True)
class TextFormat:
    """How a delimited text file is laid out; None (or 0 rows) means: detect it.

    delimiter: one of DELIMITERS (' ' is any run of blanks). decimal: '.' or ','.
    skip_rows: lines to skip before the header (or the data). encoding: a Python codec name.
    """

    delimiter: str | None = setting(
        None, help='Text column delimiter: , ; | tab space; detected where none is given'
    )
    decimal: str | None = setting(
        None, help='Decimal separator of text files; detected where none is given', choices=DECIMALS
    )
    skip_rows: int = setting(
        0,
        unit='lines',
        help='Lines before the header of a text file (0: found from the first row of numbers)',
        limits=(0, 1_000_000),
    )
    encoding: str | None = setting(
        None, help='Text encoding; where none is given: the BOM, UTF-8, else detected'
    )

    def __post_init__(self) -> None:
        if self.delimiter is not None and self.delimiter not in DELIMITERS:
            raise BadInputError(
                f'delimiter {self.delimiter!r} is not one of {", ".join(map(repr, DELIMITERS))} '
                f'(or {", ".join(DELIMITER_NAMES)})'
            )
        if self.decimal is not None and self.decimal not in DECIMALS:
            raise BadInputError(f"decimal separator {self.decimal!r} must be '.' or ','")
        if self.decimal is not None and self.decimal == self.delimiter:
            raise BadInputError(
                f'the delimiter and the decimal separator are both {self.decimal!r}'
            )
        if self.skip_rows < 0:
            raise BadInputError(f'skip_rows must not be negative, got {self.skip_rows}')
        if self.encoding is not None:
            try:
                codecs.lookup(self.encoding)
            except LookupError:
                raise BadInputError(f'unknown text encoding {self.encoding!r}') from None


DETECT = TextFormat()
"""Everything detected from the file."""


def delimiter_from_name(text: str) -> str:
    """A delimiter as a command line gives it: the character or its name (tab, semicolon...)."""
    delimiter = DELIMITER_NAMES.get(text.strip().lower(), '\t' if text == '\\t' else text)
    if delimiter not in DELIMITERS:
        raise BadInputError(
            f'delimiter {text!r} is not one of {", ".join(DELIMITER_NAMES)} '
            f'or {", ".join(map(repr, DELIMITERS))}'
        )
    return delimiter
