"""Every string in the HTML report that came from a file or a user is text, never markup.

Beyond the title and a file name (test_report_browser.py): nominal level names given on the
command line (tables, figure titles and alt texts, section headings), the name of a file
whose hit is flagged and left out of the fit (the fit's note), and a damaged bag's name and
problems (the session's list of problems, every hit's source). The page is parsed for its
tags and attributes here; test_report_browser.py opens the same page in Chromium.
"""

import html.parser
import shutil

import numpy as np
import pytest
from damaged_records import RATE_HZ, session

from fmm_ros.cli import main
from fmm_ros.core.signal.records import write_impact_csv
from fmm_ros.io.bags.writer import BagWriter

HOSTILE = '"><img src=x onerror=alert(1)><script>alert(2)</script>'
HOSTILE_LEVEL = '<i>low</i><script>alert(3)</script>'  # NAME=FORCE_N: no '=' in a name
HOSTILE_NAME = '"><img src=x onerror=alert(4)>'  # a file name cannot hold a slash
# Tags the report itself writes.
PAGE_TAGS = {
    'html', 'head', 'meta', 'title', 'style', 'body', 'h1', 'h2', 'h3', 'p', 'nav', 'ul',
    'li', 'a', 'b', 'table', 'thead', 'tbody', 'tr', 'th', 'td', 'figure', 'img',
    'figcaption', 'details', 'summary',
}  # fmt: skip


class _Page(html.parser.HTMLParser):
    """Tags, attributes and text of a page."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.tags, self.attributes, self.text = set(), [], []

    def handle_starttag(self, tag, attrs):
        self.tags.add(tag)
        self.attributes += [name for name, _ in attrs]

    def handle_data(self, data):
        self.text.append(data)


def hostile_session(folder):
    """CSV hits named with markup (one clipped), a damaged bag named so, a report of them."""
    hits, _ = session('clipped', seed=21, damaged=(2,))
    for number, hit in enumerate(hits):
        write_impact_csv(
            folder / f'{HOSTILE_NAME}{number}.csv',
            hit.record.force_n,
            hit.record.velocity_m_s,
            RATE_HZ,
        )
    bag = folder / f'{HOSTILE_NAME}bag'
    record = hits[1].record
    with BagWriter(bag, time_origin_ns=10**18) as writer:
        writer.write_signals(record.force_n, record.velocity_m_s, RATE_HZ)
    storage = next(bag.glob('*.mcap'))
    storage.write_bytes(storage.read_bytes()[: storage.stat().st_size * 3 // 4])
    (bag / 'metadata.yaml').unlink()  # a crashed recording: read by scanning, damage named
    out = folder / 'report'
    code = main(
        [
            'report',
            *sorted(str(path) for path in folder.glob('*.csv')),
            str(bag),
            '-o',
            str(out),
            '--level',
            f'{HOSTILE_LEVEL}=450',
            '--level',
            '<b>medium</b>=1000',
            '--level',
            'high=1450',
            '--tolerance-n',
            '150',
            '--title',
            HOSTILE,
            '--dpi',
            '30',
        ]
    )
    return code, out


@pytest.fixture(scope='module')
def hostile_report(tmp_path_factory):
    folder = tmp_path_factory.mktemp('hostile')
    code, out = hostile_session(folder)
    yield code, out
    shutil.rmtree(folder, ignore_errors=True)


@pytest.mark.slow
def test_strings_from_files_and_users_are_text_in_the_report(hostile_report):
    code, out = hostile_report
    assert code == 1  # the bag was damaged: the page is written, the problem reported
    page = _Page()
    page.feed((out / 'index.html').read_text(encoding='utf-8'))
    assert page.tags <= PAGE_TAGS and 'script' not in page.tags
    assert not [name for name in page.attributes if name.startswith('on')]
    text = ''.join(page.text)
    assert text.count(HOSTILE) >= 2  # title, h1
    assert text.count(HOSTILE_LEVEL) >= 3 and '<b>medium</b>' in text  # tables, headings
    assert text.count(HOSTILE_NAME) >= 8  # inputs, hit sources, problems, the fit's note
    assert f'{HOSTILE_NAME}2.csv: clipped' in text  # the fit's note: left out, by name
    assert f'{HOSTILE_NAME}bag' in text and 'the recording was not closed' in text
    # Figure files are named from level names made safe, inside the report folder only.
    assert all(path.parent == out for path in out.rglob('*.png'))
    assert np.all([path.name.isascii() and '<' not in path.name for path in out.glob('*')])
