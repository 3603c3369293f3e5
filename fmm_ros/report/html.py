"""One self-contained HTML page: sections, text, tables and figures, plus each figure as a PNG.

The page embeds every figure as a base64 PNG, so it can be mailed or archived alone; the same
bytes are written next to it as `<name>.png` (linked from the caption) for slides and papers.
Everything put on the page is HTML-escaped unless handed over as `Markup`.
"""

from __future__ import annotations

import base64
import contextlib
import html
import re
from collections.abc import Callable, Iterator, Sequence
from datetime import datetime, timezone
from pathlib import Path

from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.legend import Legend

from fmm_ros.constants import REPORT_DPI
from fmm_ros.errors import BadInputError
from fmm_ros.report.plotting import png_bytes

_STYLE = """
body { font-family: system-ui, sans-serif; max-width: 60rem; margin: 1rem auto; padding: 0 1rem;
       color: #222; line-height: 1.4; }
h1 { font-size: 1.5rem; } h2 { font-size: 1.25rem; border-bottom: 1px solid #ccc;
       margin-top: 2rem; } h3 { font-size: 1.05rem; }
table { border-collapse: collapse; font-size: 0.85rem; margin: 0.5rem 0; }
th, td { border: 1px solid #ccc; padding: 0.15rem 0.45rem; text-align: right; }
th { background: #f0f0f0; } td.text, th.text { text-align: left; }
tr.rejected td { background: #fde8e8; }
figure { margin: 1rem 0; } figure img { max-width: 100%; border: 1px solid #eee; }
figcaption { font-size: 0.85rem; color: #444; }
.note { color: #555; font-style: italic; }
nav ul { columns: 2; font-size: 0.9rem; }
details { margin: 0.2rem 0; } summary { cursor: pointer; font-size: 0.9rem; }
details[open] > summary { font-weight: 600; }
"""

_NAME = re.compile(r'^[A-Za-z0-9_.-]+$')

# The figure files the last page written in a folder saved: a new page in the same folder
# removes the ones it does not write again (and nothing else), so no stale hit is left.
FIGURE_LIST = '.fmm_report_figures'


class Markup(str):
    """Text that is already HTML (built by this module or escaped by the caller)."""


def escape(value: object) -> str:
    """Text as HTML, unless it is `Markup` already."""
    return value if isinstance(value, Markup) else html.escape(str(value))


def link(href: str, text: object) -> Markup:
    """An <a> element with escaped target and text."""
    return Markup(f'<a href="{html.escape(href, quote=True)}">{escape(text)}</a>')


def alt_text(figure: Figure) -> str:
    """What a figure shows, in the words a sighted reader reads on it ('' if it has none).

    Its title, then each panel's title, quantity against what, and legend: the page's alt
    text for the figure (for a screen reader, or where the image does not load). Taken from
    the figure itself, it names what is plotted in every figure and stays true when a figure
    changes; the caption beside it says what the plot means.
    """
    panels = []
    for ax in figure.axes:
        titles = ', '.join(filter(None, (ax.get_title(loc) for loc in ('left', 'center', 'right'))))
        legend = ax.get_legend()
        panels.append(
            ' '.join(
                filter(
                    None,
                    (
                        f'{titles}:' if titles else '',
                        ' against '.join(filter(None, (ax.get_ylabel(), _x_label(ax)))),
                        f'(legend: {_legend_text(legend)})' if legend is not None else '',
                    ),
                )
            )
        )
    panels = [panel for panel in panels if panel]
    text = ' '.join(
        filter(
            None,
            (
                f'{figure.get_suptitle()}.' if figure.get_suptitle() else '',
                f'{len(panels)} panels:' if len(panels) > 1 else '',
                '; '.join(panels) + '.' if panels else '',
                *(f'Legend: {_legend_text(legend)}.' for legend in figure.legends),
            ),
        )
    )
    return ' '.join(text.split())  # one line: labels may break theirs


def _x_label(ax: Axes) -> str:
    """The axes' x label, else the one of the nearest panel below it in its column.

    Stacked panels label only the bottom one, and a reader takes that label for all.
    """
    spec = ax.get_subplotspec()
    if ax.get_xlabel() or spec is None:
        return ax.get_xlabel()
    below = [
        (other_spec.rowspan.start, other.get_xlabel())
        for other in ax.figure.axes
        if (other_spec := other.get_subplotspec()) is not None
        and other.get_xlabel()
        and other_spec.colspan == spec.colspan
        and other_spec.rowspan.start > spec.rowspan.start
    ]
    return min(below)[1] if below else ''


def _legend_text(legend: Legend) -> str:
    """A legend's entries, comma separated."""
    return ', '.join(text.get_text() for text in legend.get_texts())


class Page:
    """An HTML report being assembled in `out_dir`; `write()` saves index.html.

    Figures are rendered and saved as PNG as soon as they are added, then cleared, so a long
    report holds no more figures than it reuses. progress, when given, is told of each.
    """

    def __init__(
        self,
        out_dir: str | Path,
        title: str,
        *,
        dpi: float = REPORT_DPI,
        progress: Callable[[str], None] | None = None,
    ) -> None:
        self.out_dir = Path(out_dir)
        self._progress = progress
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.title = title
        self.dpi = dpi
        self.figures: list[Path] = []
        self._body: list[str] = []
        self._sections: list[tuple[str, str]] = []

    def section(self, title: str, anchor: str) -> None:
        """Start a top-level section (listed in the page's contents)."""
        self._sections.append((anchor, title))
        self._body.append(f'<h2 id="{html.escape(anchor, quote=True)}">{escape(title)}</h2>')

    def subsection(self, title: str) -> None:
        """A heading inside the current section."""
        self._body.append(f'<h3>{escape(title)}</h3>')

    @contextlib.contextmanager
    def collapsed(self, summary: object) -> Iterator[None]:
        """What is added inside is folded under a one-line summary the reader opens.

        A plain <details> element: no script, and the browser's find-in-page opens it. A
        session's per-hit figures are folded so the page is read by its levels first (30
        hits drawn open made a 45,000-pixel page).
        """
        self._body.append(f'<details><summary>{escape(summary)}</summary>')
        try:
            yield
        finally:
            self._body.append('</details>')

    def text(self, content: object, *, note: bool = False) -> None:
        """A paragraph (note: set in the muted style, for what is absent and why)."""
        css = ' class="note"' if note else ''
        self._body.append(f'<p{css}>{escape(content)}</p>')

    def items(self, entries: Sequence[object]) -> None:
        """A bulleted list."""
        self._body.append(
            '<ul>' + ''.join(f'<li>{escape(entry)}</li>' for entry in entries) + '</ul>'
        )

    def table(
        self,
        headers: Sequence[str],
        rows: Sequence[Sequence[object]],
        *,
        text_columns: Sequence[int] = (),
        row_classes: Sequence[str] | None = None,
        table_id: str = '',
    ) -> None:
        """A table; text_columns are left-aligned (numbers align right)."""

        def cell(tag: str, column: int, value: object) -> str:
            css = ' class="text"' if column in text_columns else ''
            return f'<{tag}{css}>{escape(value)}</{tag}>'

        ident = f' id="{html.escape(table_id, quote=True)}"' if table_id else ''
        lines = [
            f'<table{ident}><thead><tr>'
            + ''.join(cell('th', i, h) for i, h in enumerate(headers))
            + '</tr></thead>',
            '<tbody>',
        ]
        for number, row in enumerate(rows):
            css = row_classes[number] if row_classes else ''
            css = f' class="{html.escape(css, quote=True)}"' if css else ''
            lines.append(
                f'<tr{css}>' + ''.join(cell('td', i, v) for i, v in enumerate(row)) + '</tr>'
            )
        lines.append('</tbody></table>')
        self._body.append('\n'.join(lines))

    def figure(self, name: str, figure: Figure, caption: object, *, keep: bool = False) -> Path:
        """Render the figure to `<name>.png` next to the page and embed the same PNG.

        Its alt text is made of the figure's own words (`alt_text`). The figure is cleared
        afterwards unless keep (the caller draws into it again).
        """
        if not _NAME.match(name):
            raise BadInputError(f'figure name {name!r} must be letters, digits, _ . - only')
        if self._progress:
            self._progress(f'drawing figure {len(self.figures) + 1}: {name}')
        path = self.out_dir / f'{name}.png'
        if path in self.figures:
            raise BadInputError(f'figure {name!r} is already on the page')
        data = png_bytes(figure, self.dpi)
        alt = alt_text(figure) or str(caption)  # a figure without words: its caption
        if not keep:
            figure.clear()
        path.write_bytes(data)
        self.figures.append(path)
        encoded = base64.b64encode(data).decode('ascii')
        self._body.append(
            f'<figure id="fig-{name}"><img src="data:image/png;base64,{encoded}" '
            f'alt="{html.escape(alt, quote=True)}"><figcaption>{escape(caption)} '
            f'{link(path.name, f"[{path.name}]")}</figcaption></figure>'
        )
        return path

    def write(self, filename: str = 'index.html') -> Path:
        """Write the page (contents list first) and return its path."""
        generated = datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC')
        contents = ''.join(
            f'<li><a href="#{html.escape(anchor, quote=True)}">{escape(title)}</a></li>'
            for anchor, title in self._sections
        )
        page = '\n'.join(
            [
                '<!DOCTYPE html>',
                '<html lang="en"><head><meta charset="utf-8">',
                f'<title>{escape(self.title)}</title>',
                f'<style>{_STYLE}</style></head><body>',
                f'<h1>{escape(self.title)}</h1>',
                f'<p class="note">generated {generated} by fmm_ros</p>',
                f'<nav><ul>{contents}</ul></nav>',
                *self._body,
                '</body></html>',
            ]
        )
        path = self.out_dir / filename
        path.write_text(page, encoding='utf-8')
        self._remove_stale_figures()
        return path

    def _remove_stale_figures(self) -> None:
        """Delete figures an earlier page here wrote and this one did not; list this page's."""
        listing = self.out_dir / FIGURE_LIST
        current = {path.name for path in self.figures}
        if listing.is_file():
            for name in listing.read_text(encoding='utf-8').split():
                if name not in current and name.endswith('.png') and _NAME.match(name):
                    (self.out_dir / name).unlink(missing_ok=True)
        listing.write_text(''.join(f'{name}\n' for name in sorted(current)), encoding='utf-8')
