"""What every report figure shares: an off-screen Figure, its layout, units, colours, decimation.

Figures are `matplotlib.figure.Figure` objects made without pyplot: no global figure registry,
no backend switch, nothing shown, so the report can run inside a ROS node or a test process
without a display and without changing matplotlib's state for anyone else in the process.
`png_bytes` lays one out (`place_axes`) and renders it with the Agg renderer.

Axes show convenient multiples of SI units (mm/N rather than m/N) so tick labels stay short;
the unit is always in the axis label.
"""

from __future__ import annotations

import contextlib
import io

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backend_bases import RendererBase
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.gridspec import SubplotSpec
from matplotlib.lines import Line2D
from matplotlib.ticker import FixedLocator, Locator
from PIL import Image

from fmm_ros.constants import REPORT_DPI
from fmm_ros.errors import BadInputError

# Inches: wide enough for two decades of ticks, narrow enough to sit in a page column.
FIGURE_WIDTH_IN = 7.5
PANEL_HEIGHT_IN = 2.4
# zlib level of the PNGs: 6 (the default) makes them 6 % smaller than 3 for 40 % more time.
PNG_COMPRESS_LEVEL = 3
# Space between the decorations of neighbouring axes, and around them at the canvas edge.
LAYOUT_PAD_PT = 4.0
# A grid cell smaller than this after the margins means the labels cannot fit [inches].
MIN_AXES_IN = 0.5
# Where `new_figure` puts the axes before `place_axes` measures them [inches]: margins for
# tick labels and an axis label, room for a suptitle, gaps for a row's x labels and the
# next row's title (less where the rows share x and inner ones have no x labels).
GUESS_LEFT_IN = 0.75
GUESS_RIGHT_IN = 0.15
GUESS_BOTTOM_IN = 0.5
GUESS_TOP_IN = 0.1
GUESS_TITLE_IN = 0.3
GUESS_COLUMN_GAP_IN = 0.9
GUESS_ROW_GAP_IN = 0.65
GUESS_SHARED_ROW_GAP_IN = 0.3

# Display units: receptance and mobility in mm per N (per N*s), as the CLI shows them
# (`fmm_ros.constants.RECEPTANCE_DISPLAY_UNIT`, scale `MM_PER_M`), times in ms.
MS_PER_S = 1e3
FREQUENCY_LABEL = 'frequency [Hz]'

# Levels in ascending force take these colours everywhere (matplotlib's tab10 cycle).
_LEVEL_COLOURS = (
    'tab:blue',
    'tab:orange',
    'tab:green',
    'tab:purple',
    'tab:brown',
    'tab:pink',
    'tab:olive',
    'tab:cyan',
)
MEAN_COLOUR = 'black'
MODEL_COLOUR = 'tab:red'
REJECTED_COLOUR = 'tab:gray'

# A `TraceLine` holds a min/max envelope of this many points until it is drawn.
MAX_PLOT_POINTS = 4000


def level_colour(index: int) -> str:
    """Colour of the index-th level (in ascending force), the same in every figure."""
    return _LEVEL_COLOURS[index % len(_LEVEL_COLOURS)]


def new_figure(
    rows: int = 1,
    columns: int = 1,
    *,
    height_in: float | None = None,
    sharex: bool | str = False,
    title: str = '',
) -> tuple[Figure, np.ndarray]:
    """A Figure with a grid of axes (a flat array), laid out when `png_bytes` renders it."""
    figure = Figure(
        figsize=(FIGURE_WIDTH_IN, height_in or PANEL_HEIGHT_IN * rows + 0.4), facecolor='white'
    )
    FigureCanvasAgg(figure)
    axes = figure.subplots(rows, columns, sharex=sharex, squeeze=False).ravel()
    for ax in axes:
        ax.grid(True, linewidth=0.4, alpha=0.5)
    if title:
        figure_title(figure, title)
    # Typical margins, so the ticks `png_bytes` freezes are chosen near the final size.
    row_gap_in = GUESS_SHARED_ROW_GAP_IN if sharex in (True, 'all', 'col') else GUESS_ROW_GAP_IN
    with contextlib.suppress(ValueError):  # too small for typical labels: png_bytes says so
        _arrange(
            figure,
            GUESS_LEFT_IN,
            GUESS_RIGHT_IN,
            GUESS_BOTTOM_IN,
            GUESS_TOP_IN + (GUESS_TITLE_IN if title else 0.0),
            GUESS_COLUMN_GAP_IN,
            row_gap_in,
        )
    return figure, axes


def figure_title(figure: Figure, title: str) -> None:
    """Set the figure's title, its top one pad below the canvas edge (not 2 % of the height)."""
    figure.suptitle(title, fontsize='medium', y=1 - LAYOUT_PAD_PT / 72 / figure.get_figheight())


def png_bytes(figure: Figure, dpi: float = REPORT_DPI) -> bytes:
    """The figure laid out and rendered as an RGB PNG (Agg, no metadata, so no timestamp).

    The tick positions are frozen where the locators put them for the axes' present size
    (`new_figure` starts them at typical margins), then the layout measures the labels of
    exactly those ticks: left free, a locator picks other, wider labels for the resized
    axes (-12.5 instead of -10), which would overrun the canvas. They stay frozen
    (`thaw_ticks` frees them), so the figure keeps exactly the layout the PNG shows. One
    measurement and one draw make the PNG; matplotlib's constrained layout measured every
    axes four times and drew three times.
    """
    figure.set_dpi(dpi)
    canvas = figure.canvas
    if not isinstance(canvas, FigureCanvasAgg):
        canvas = FigureCanvasAgg(figure)
    freeze_ticks(figure)
    place_axes(figure, canvas.get_renderer())
    canvas.draw()
    # RGB: the canvas is opaque, and an alpha channel costs a fifth more to compress.
    image = Image.frombuffer(
        'RGBA', canvas.get_width_height(physical=True), canvas.buffer_rgba(), 'raw', 'RGBA', 0, 1
    ).convert('RGB')
    buffer = io.BytesIO()
    image.save(buffer, format='png', compress_level=PNG_COMPRESS_LEVEL)
    return buffer.getvalue()


def place_axes(figure: Figure, renderer: RendererBase) -> None:
    """Size the figure's grid of axes so everything drawn lies inside the canvas.

    An axes' decorations (tick labels, axis labels, title, legend, annotations) overhang its
    frame by the same amount whatever the frame's size, so one measurement of each gives
    the margins: the widest overhang of the outer rows and columns, the overhangs of both
    neighbours between them, and LAYOUT_PAD_PT between everything. The figure's own texts
    and legends stay where they are anchored (the suptitle at the top, a figure legend at
    the bottom) and the grid fits between them. Columns share one width and rows one
    height, as `Figure.subplots` made them; axes not in a grid are left alone.
    """
    grid = _grid(figure)
    if not grid:
        return
    rows, columns = grid[0][1].get_gridspec().get_geometry()
    height = figure.bbox.height
    pad = LAYOUT_PAD_PT * figure.dpi / 72
    left, right = np.zeros(columns), np.zeros(columns)
    above, below = np.zeros(rows), np.zeros(rows)
    for ax, spec in grid:
        frame, box = ax.bbox, ax.get_tightbbox(renderer)
        first_column, last_column = spec.colspan.start, spec.colspan.stop - 1
        first_row, last_row = spec.rowspan.start, spec.rowspan.stop - 1
        left[first_column] = max(left[first_column], frame.x0 - box.x0)
        right[last_column] = max(right[last_column], box.x1 - frame.x1)
        above[first_row] = max(above[first_row], box.y1 - frame.y1)
        below[last_row] = max(below[last_row], frame.y0 - box.y0)
    top, bottom = height, 0.0
    for artist in (*figure.texts, *figure.legends):
        if not (artist.get_visible() and artist.get_in_layout()):
            continue
        box = artist.get_window_extent(renderer)
        if box.height <= 0:
            continue  # an empty text
        if box.y0 + box.y1 > height:
            top = min(top, box.y0)
        else:
            bottom = max(bottom, box.y1)
    inch = figure.dpi
    _arrange(
        figure,
        (pad + left[0]) / inch,
        (pad + right[-1]) / inch,
        (bottom + pad + below[-1]) / inch,
        (height - top + pad + above[0]) / inch,
        (pad + max(right[:-1] + left[1:], default=0.0)) / inch,
        (pad + max(below[:-1] + above[1:], default=0.0)) / inch,
    )


def _arrange(
    figure: Figure,
    left_in: float,
    right_in: float,
    bottom_in: float,
    top_in: float,
    column_gap_in: float,
    row_gap_in: float,
) -> None:
    """Place the figure's grid of axes with these margins and gaps [inches]."""
    grid = _grid(figure)
    if not grid:
        return
    rows, columns = grid[0][1].get_gridspec().get_geometry()
    width, height = figure.get_size_inches()
    cell_width = (width - left_in - right_in - (columns - 1) * column_gap_in) / columns
    cell_height = (height - bottom_in - top_in - (rows - 1) * row_gap_in) / rows
    if min(cell_width, cell_height) < MIN_AXES_IN:
        raise BadInputError(
            f'a {width:.3g} x {height:.3g} in figure of {rows} x {columns} axes '
            f'leaves {cell_width:.2g} x {cell_height:.2g} in an axes inside its '
            'labels: make it larger or its labels shorter'
        )
    for ax, spec in grid:
        span_width = len(spec.colspan) * (cell_width + column_gap_in) - column_gap_in
        span_height = len(spec.rowspan) * (cell_height + row_gap_in) - row_gap_in
        ax_left = left_in + spec.colspan.start * (cell_width + column_gap_in)
        ax_top = height - top_in - spec.rowspan.start * (cell_height + row_gap_in)
        ax.set_position(
            [
                ax_left / width,
                (ax_top - span_height) / height,
                span_width / width,
                span_height / height,
            ]
        )
        ax.set_in_layout(True)  # set_position takes an axes out of any layout


def _grid(figure: Figure) -> list[tuple[Axes, SubplotSpec]]:
    """The figure's axes that sit in a grid (`Figure.subplots`), with their cells."""
    cells = [(ax, ax.get_subplotspec()) for ax in figure.axes]
    return [(ax, spec) for ax, spec in cells if spec is not None]


class _FrozenLocator(FixedLocator):
    """The ticks a locator gave at one size, fixed; `original` is that locator."""

    def __init__(self, locations: np.ndarray, original: Locator) -> None:
        super().__init__(locations)
        self.original = original


def freeze_ticks(figure: Figure) -> None:
    """Fix every axis' major and minor tick positions where its locators now put them."""
    for ax in figure.axes:
        for axis in (ax.xaxis, ax.yaxis):
            major, minor = axis.get_major_locator(), axis.get_minor_locator()
            if not isinstance(major, _FrozenLocator):  # a shared axis is frozen already
                axis.set_major_locator(_FrozenLocator(axis.get_majorticklocs(), major))
            if not isinstance(minor, _FrozenLocator):
                axis.set_minor_locator(_FrozenLocator(axis.get_minorticklocs(), minor))


def thaw_ticks(figure: Figure) -> None:
    """Give every axis its own locators back (before drawing new data into the figure)."""
    for ax in figure.axes:
        for axis in (ax.xaxis, ax.yaxis):
            major, minor = axis.get_major_locator(), axis.get_minor_locator()
            if isinstance(major, _FrozenLocator):
                axis.set_major_locator(major.original)
            if isinstance(minor, _FrozenLocator):
                axis.set_minor_locator(minor.original)


class TraceLine(Line2D):
    """A long time series (x increasing) drawn as the min and max of each pixel column.

    Drawn so, it covers the pixels the full series would (noise band, peaks and gaps
    included) at two points a column: a 4 s decay at 10 kHz is 40,000 points, some 50 for
    each column of a report's axes, and Agg's time grows with the points (the zigzag of a
    noise band defeats its path simplification). The columns are those of the axes when
    drawn, at whatever size and dpi. Until then the line holds the `envelope` of the
    series (same extremes, so autoscaling and layout see the full series' limits).
    """

    def __init__(self, x: np.ndarray, y: np.ndarray, **kwargs) -> None:
        super().__init__([], [], **kwargs)
        self.set_trace(x, y)

    def set_trace(self, x: np.ndarray, y: np.ndarray) -> None:
        """Replace the series."""
        self._trace = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        self.set_data(*envelope(*self._trace))

    def draw(self, renderer: RendererBase) -> None:
        """Draw the series reduced to the pixel columns the axes now have."""
        if self.axes is not None and self.axes.get_xscale() == 'linear':
            self.set_data(*pixel_envelope(*self._trace, self.axes.get_xlim(), self.axes.bbox.width))
        super().draw(renderer)


def plot_trace(ax: Axes, x: np.ndarray, y: np.ndarray, **kwargs) -> TraceLine:
    """Add a `TraceLine` of y against x (Line2D keywords) to ax, autoscaled like `plot`."""
    line = TraceLine(x, y, **kwargs)
    ax.add_line(line)
    ax.autoscale_view()
    return line


def pixel_envelope(
    x: np.ndarray, y: np.ndarray, view: tuple[float, float], width_px: float
) -> tuple[np.ndarray, np.ndarray]:
    """The min and max of y in each pixel column of an axes width_px wide showing view of x.

    x increasing. Samples outside the view are dropped but for one each side, which carries
    the line to the edge. A series no longer than two points a column comes back whole.
    """
    first, last = view
    low_x, high_x = min(first, last), max(first, last)
    start = max(int(np.searchsorted(x, low_x, side='right')) - 1, 0)
    stop = min(int(np.searchsorted(x, high_x, side='left')) + 1, x.size)
    x, y = x[start:stop], y[start:stop]
    if x.size <= 2 * width_px + 4 or first == last:
        return x, y
    column = np.floor((x - first) * (width_px / (last - first)))
    return _extremes(x, y, np.flatnonzero(np.diff(column, prepend=np.nan)))


def envelope(
    x: np.ndarray, y: np.ndarray, max_points: int = MAX_PLOT_POINTS
) -> tuple[np.ndarray, np.ndarray]:
    """A long series reduced to the min and max of each of max_points / 2 bins, in x order.

    Drawn as a line it covers the pixels the full series would (noise band and peaks
    included) when the bins are no wider than a pixel, at a small fraction of the cost: a
    33 s record at 10 kHz is 330,000 points. A bin of NaN samples (a gap in the record)
    stays NaN, so the gap shows as a break in the line.
    """
    if y.size <= max_points:
        return x, y
    return _extremes(x, y, np.linspace(0, y.size, max_points // 2 + 1).astype(np.int64)[:-1])


def _extremes(x: np.ndarray, y: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Min at the first x and max at the last x of each bin (bins begin at starts)."""
    with np.errstate(invalid='ignore'):
        low = np.fmin.reduceat(y, starts)
        high = np.fmax.reduceat(y, starts)
    # Alternating min and max at the bin's first and last x keeps the trace monotone in x.
    xs = np.empty(2 * starts.size)
    ys = np.empty(2 * starts.size)
    xs[0::2] = x[starts]
    xs[1::2] = x[np.append(starts[1:], x.size) - 1]
    ys[0::2] = low
    ys[1::2] = high
    return xs, ys


def odd_harmonics(natural_frequency_hz: float, top_hz: float) -> list[tuple[int, float]]:
    """(n, n f_n) for the odd multiples n >= 3 of f_n up to top_hz (the paper's Fig. 24)."""
    if not np.isfinite(natural_frequency_hz) or natural_frequency_hz <= 0:
        return []
    count = int(top_hz // natural_frequency_hz)
    return [(n, n * natural_frequency_hz) for n in range(3, count + 1, 2)]
