"""How a report page is drawn, declared once for `fmm report` and `fmm campaign`.

Standard library only (with the package's constants), so `fmm --help` shows it without
matplotlib.
"""

from dataclasses import dataclass

from fmm_ros.constants import REPORT_DPI
from fmm_ros.core.settings import setting


@dataclass(frozen=True)
class PageSettings:
    """A report page's title and the resolution of its figures."""

    title: str = setting('Impact session report', help='Page title')
    dpi: float = setting(
        REPORT_DPI,
        unit='dots per inch',
        help='PNG resolution of the figures',
        limits=(10.0, 2400.0),
    )
