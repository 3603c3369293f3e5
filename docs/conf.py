"""Sphinx configuration of the fmm_ros documentation site (`make docs`).

Pages are MyST Markdown. The reference is made from the code at build time: the `fmm`
command, the nodes' parameters and the messages by the local extension `_ext/fmm_reference.py`,
the Python API by autodoc/autosummary. The gallery runs `docs/examples/plot_*.py` with
sphinx-gallery. Everything the HTML needs ships with the theme (furo): no CDN.
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / '_ext'))

# matplotlib draws off-screen, into files only.
os.environ.setdefault('MPLBACKEND', 'Agg')

project = 'fmm_ros'
author = 'fmm_ros maintainers'
copyright = '2026, fmm_ros maintainers'  # noqa: A001 (Sphinx's own setting name)

extensions = [
    'myst_parser',
    'sphinx.ext.autodoc',
    'sphinx.ext.autosummary',
    'sphinx_gallery.gen_gallery',
    'fmm_reference',
]

source_suffix = {'.md': 'markdown', '.rst': 'restructuredtext'}
# examples/ holds the gallery's sources; sphinx-gallery renders them into auto_examples/.
exclude_patterns = ['_build', 'examples', 'Thumbs.db', '.DS_Store']
root_doc = 'index'

myst_heading_anchors = 3
myst_enable_extensions = ['colon_fence', 'deflist']

autosummary_generate = True
# Packages re-export their modules' names (`__all__`); each object is documented once, in the
# module that defines it, so a reference to it has one target.
autodoc_default_options = {'members': True, 'show-inheritance': True, 'ignore-module-all': True}
autodoc_member_order = 'bysource'
autodoc_typehints = 'description'
autodoc_typehints_format = 'short'
# Annotations name types of other libraries (numpy, matplotlib, rclpy and the message
# packages, rosbags, the standard library), which this offline build has no inventory for
# (intersphinx would download one): they stay plain text instead of failing as broken links.
# So do private helpers (a leading underscore) and type variables that annotations name.
_EXTERNAL = (
    'foxglove|np|numpy|npt|matplotlib|rclpy|rcl_interfaces|builtin_interfaces|diagnostic_msgs|std_msgs',
    'fmm_interfaces|rosbags|tqdm|dask|distributed|pyarrow|yaml|argparse|pathlib|subprocess',
    'os|array|types|abc|collections|typing|dataclasses|enum|datetime|io|logging|threading',
    'tornado|asyncio',
)
nitpick_ignore_regex = [
    (r'py:(class|obj|data|exc|func)', rf'({"|".join(_EXTERNAL)})(\..*)?'),
    (r'py:(class|obj|data|exc)', r'Path|PathLike|Application'),
    (r'py:(class|obj|data|exc)', r'fmm_ros(\.\w+)*\._\w+'),
    (r'py:(class|obj|data|exc)', r'fmm_ros\.ros\.graph\.NodeT'),
]


_BAR = re.compile(r'(?<!\\)\|')


def _bars_as_text(app, what, name, obj, options, lines: list[str]) -> None:
    """Escape every bar of a docstring, so |x| shows as written.

    Docstrings write magnitudes as |x| in plain text, as the code's comments do, and never use
    reStructuredText substitutions, which a pair of bars would otherwise be taken for.
    """
    lines[:] = [_BAR.sub(r'\\|', line) for line in lines]


def _skip_foreign(app, what, name, obj, skip, options) -> bool | None:
    """Leave out members a class gets from another library (matplotlib's generated `set`).

    Their docstrings are written for that library's own documentation build.
    """
    module = getattr(obj, '__module__', None)
    if what == 'class' and isinstance(module, str) and not module.startswith('fmm_ros'):
        return True
    return None


def _drop_timing_pages(app, exception) -> None:
    """Remove sphinx-gallery's execution-time pages, which load DataTables from a CDN.

    Lab PCs are offline: nothing of the site may load from the network.
    """
    if exception is None:
        for page in Path(app.outdir).rglob('sg_execution_times.html'):
            page.unlink()


def setup(app) -> None:
    """Connect the docstring hooks, and drop the pages that would reach the network."""
    app.connect('autodoc-process-docstring', _bars_as_text)
    app.connect('autodoc-skip-member', _skip_foreign)
    app.connect('build-finished', _drop_timing_pages)


sphinx_gallery_conf = {
    'examples_dirs': 'examples',
    'gallery_dirs': 'auto_examples',
    'filename_pattern': r'/plot_',
    'download_all_examples': False,
    'remove_config_comments': True,
    'within_subsection_order': 'FileNameSortKey',
    'image_scrapers': ('matplotlib',),
    'matplotlib_animations': False,
    'show_memory': False,
    'plot_gallery': 'True',
}

html_theme = 'furo'
html_title = 'fmm_ros'
html_static_path: list[str] = []
