"""What every report figure shares: an off-screen Figure, display units, colours, decimation.

Figures are `matplotlib.figure.Figure` objects made without pyplot: no global figure registry,
no backend switch, nothing shown, so the report can run inside a ROS node or a test process
without a display and without changing matplotlib's state for anyone else in the process.
`png_bytes` renders one with the Agg renderer (what `savefig` picks for PNG by itself).

Axes show convenient multiples of SI units (mm/N rather than m/N) so tick labels stay short;
the unit is always in the axis label.
"""

from __future__ import annotations

import io

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import FixedLocator

# Inches: wide enough for two decades of ticks, narrow enough to sit in a page column.
FIGURE_WIDTH_IN = 7.5
PANEL_HEIGHT_IN = 2.4
DEFAULT_DPI = 110

# Display scale factors from SI values: receptance and mobility in mm per N (per N*s).
MM_PER_M = 1e3
MS_PER_S = 1e3
RECEPTANCE_UNIT = 'mm/N'
MOBILITY_UNIT = 'mm/(N·s)'
FREQUENCY_LABEL = 'frequency [Hz]'

# Levels in ascending force take these colours everywhere (matplotlib's tab10 cycle).
_LEVEL_COLOURS = ('tab:blue', 'tab:orange', 'tab:green', 'tab:purple', 'tab:brown',
                  'tab:pink', 'tab:olive', 'tab:cyan')
MEAN_COLOUR = 'black'
MODEL_COLOUR = 'tab:red'
REJECTED_COLOUR = 'tab:gray'

# Time series longer than this are drawn as a per-bin min/max envelope (see `envelope`).
MAX_PLOT_POINTS = 4000


def level_colour(index: int) -> str:
    """Colour of the index-th level (in ascending force), the same in every figure."""
    return _LEVEL_COLOURS[index % len(_LEVEL_COLOURS)]


def new_figure(rows: int = 1, columns: int = 1, *, height_in: float | None = None,
               sharex: bool | str = False, title: str = '') -> tuple[Figure, np.ndarray]:
    """A constrained-layout Figure (labels never clipped) and its axes as a flat array."""
    figure = Figure(figsize=(FIGURE_WIDTH_IN, height_in or PANEL_HEIGHT_IN * rows + 0.4),
                    layout='constrained')
    axes = figure.subplots(rows, columns, sharex=sharex, squeeze=False).ravel()
    for ax in axes:
        ax.grid(True, linewidth=0.4, alpha=0.5)
    if title:
        figure.suptitle(title, fontsize='medium')
    return figure, axes


def png_bytes(figure: Figure, dpi: float = DEFAULT_DPI) -> bytes:
    """The figure rendered as a PNG (Agg renderer, white background, no timestamp).

    Tick positions are fixed after a first layout pass: the constrained layout sizes the
    margins for the tick labels it sees, and shrinking the axes can make the locator pick
    other, wider labels (-12.5 instead of -10), which then overrun the figure edge. With the
    ticks frozen the second pass converges and nothing is clipped.
    """
    figure.set_dpi(dpi)
    figure.draw_without_rendering()
    for ax in figure.axes:
        for axis in (ax.xaxis, ax.yaxis):
            axis.set_major_locator(FixedLocator(axis.get_majorticklocs()))
    buffer = io.BytesIO()
    figure.savefig(buffer, format='png', dpi=dpi, facecolor='white',
                   metadata={'Software': None})
    return buffer.getvalue()


def envelope(x: np.ndarray, y: np.ndarray, max_points: int = MAX_PLOT_POINTS
             ) -> tuple[np.ndarray, np.ndarray]:
    """A long series reduced to the min and max of each of max_points / 2 bins, in x order.

    Drawn as a line it covers exactly the pixels the full series would (noise band and peaks
    included) at a small fraction of the cost: a 33 s record at 10 kHz is 330,000 points,
    a page of such plots would take seconds each to render. A bin of NaN samples (a gap in
    the record) stays NaN, so the gap shows as a break in the line.
    """
    n = y.size
    if n <= max_points:
        return x, y
    bins = max_points // 2
    edges = np.linspace(0, n, bins + 1).astype(np.int64)
    starts = edges[:-1]
    with np.errstate(invalid='ignore'):
        low = np.fmin.reduceat(y, starts)
        high = np.fmax.reduceat(y, starts)
    # Alternating min and max at the bin's first and last x keeps the trace monotone in x.
    xs = np.empty(2 * bins)
    ys = np.empty(2 * bins)
    xs[0::2] = x[starts]
    xs[1::2] = x[edges[1:] - 1]
    ys[0::2] = low
    ys[1::2] = high
    return xs, ys


def odd_harmonics(natural_frequency_hz: float, top_hz: float) -> list[tuple[int, float]]:
    """(n, n f_n) for the odd multiples n >= 3 of f_n up to top_hz (the paper's Fig. 24)."""
    if not np.isfinite(natural_frequency_hz) or natural_frequency_hz <= 0:
        return []
    count = int(top_hz // natural_frequency_hz)
    return [(n, n * natural_frequency_hz) for n in range(3, count + 1, 2)]


def value_with_error(value: float, stderr: float) -> str:
    """'0.1130004 ± 0.0000014': the value to the second significant digit of its error."""
    if not (np.isfinite(value) and np.isfinite(stderr) and stderr > 0):
        return f'{value:.5g}'
    decimals = min(12, max(0, 1 - int(np.floor(np.log10(stderr)))))
    return f'{value:.{decimals}f} ± {stderr:.{decimals}f}'
