"""The one writer of benchmarks/RESULTS.md: each benchmark's full run replaces its own section.

A section is delimited by HTML comments naming the benchmark, so runs of different scripts
never touch each other's figures. Every section is stamped with the date, the machine
(cores, load averages before the run) and the command that made it, so a reader knows what
the figures were measured against. Quick runs (`--quick`, as CI runs every benchmark) check
that the script works and write nothing.
"""

from __future__ import annotations

import contextlib
import datetime
import io
import os
import platform
import re
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TextIO

RESULTS = Path(__file__).resolve().with_name('RESULTS.md')
HEADER = (
    '# Benchmark results\n\n'
    'Written by the benchmark scripts themselves (`benchmarks/results_file.py`), one section '
    'each, replaced on every full run; never edited by hand. Each figure stands beside its '
    'baseline from the same run and the machine load it was measured under.\n'
)


def machine_line() -> str:
    """Cores, load averages and Python: what a figure was measured on."""
    load = ', '.join(f'{value:.2f}' for value in os.getloadavg())
    python = platform.python_version()
    return f'{os.cpu_count()} cores, load averages {load} (1/5/15 min), Python {python}'


def write_section(name: str, body_markdown: str, *, quick: bool, path: Path = RESULTS) -> None:
    """Replace benchmark `name`'s section of RESULTS.md by `body_markdown`; quick runs skip."""
    if quick:
        return
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%d %H:%M UTC')
    command = ' '.join(['python', *(Path(sys.argv[0]).name, *sys.argv[1:])])
    section = (
        f'<!-- {name} -->\n## {name}\n\n'
        f'_{stamp}; {machine_line()}; `{command}`_\n\n{body_markdown.strip()}\n<!-- /{name} -->\n'
    )
    text = path.read_text(encoding='utf-8') if path.exists() else HEADER
    pattern = _section_pattern(name)
    if pattern.search(text):
        text = pattern.sub(lambda _: section, text)
    else:
        text = text.rstrip('\n') + '\n\n' + section
    path.write_text(text, encoding='utf-8')


def read_section(name: str, path: Path = RESULTS) -> str:
    """Benchmark `name`'s section of RESULTS.md, its markers included ('' if it has none)."""
    found = _section_pattern(name).search(path.read_text(encoding='utf-8'))
    return found.group(0) if found else ''


def _section_pattern(name: str) -> re.Pattern[str]:
    """A section of benchmark `name`, from its opening marker to its closing one."""
    return re.compile(rf'<!-- {re.escape(name)} -->\n.*?<!-- /{re.escape(name)} -->\n', re.S)


@contextlib.contextmanager
def recorded(name: str, *, quick: bool) -> Iterator[None]:
    """Print as usual; a full run that ends without error writes what it printed.

    The printout becomes benchmark `name`'s section of RESULTS.md (its tables hold each
    figure beside its baseline from the same run); quick runs write nothing, and nor does
    `--help` (argparse's exit status 0, a usage text and no figures).
    """
    quick = quick or not {'-h', '--help'}.isdisjoint(sys.argv[1:])
    printed = io.StringIO()
    try:
        with contextlib.redirect_stdout(_Tee(sys.stdout, printed)):
            yield
    except SystemExit as done:  # `raise SystemExit(main())`: status 0 is a finished run
        if done.code not in (0, None):
            raise
        write_section(name, _fenced(printed.getvalue()), quick=quick)
        raise
    write_section(name, _fenced(printed.getvalue()), quick=quick)


def _fenced(text: str) -> str:
    """Printed output as a Markdown code block."""
    return f'```text\n{text.strip()}\n```'


QUICK_HELP = 'a few repeats at small sizes (as CI runs it, to catch a crash); writes nothing'


class _Tee(io.TextIOBase):
    """A text stream writing to several at once."""

    def __init__(self, *streams: TextIO) -> None:
        self._streams = streams

    def write(self, text: str) -> int:
        for stream in self._streams:
            stream.write(text)
        return len(text)

    def flush(self) -> None:
        for stream in self._streams:
            stream.flush()
