"""The report in a real browser (issue: check the page in headless Chromium): it renders with
no console message, script error or failed load, every figure decodes, every figure's alt text
says what it shows, and text from the inputs (title, file names, level names, a damaged bag's
problems) is shown, never run."""

import contextlib
import io
import json
import re

import pytest
import test_report_escaping as escaping
from browser import visit
from PIL import Image
from test_report import DURATION_S, RATE_HZ, TEST_DPI, write_csv_session

from fmm_ros.cli import main
from fmm_ros.core.signal.records import write_impact_csv
from fmm_ros.sim.excitation import impact_record

pytestmark = pytest.mark.slow

# Words each figure's alt text must hold, by figure name (a level's name is added for the
# figures of one level, the hit's impact id for a hit's).
ALT_WORDS = {
    'impulses': ('peak force [N]', 'impulse [N·s]'),
    'linearity': ('peak |receptance|', 'against impulse'),
    'levels_receptance': ('|receptance|', 'against frequency'),
    'friction': ('μ', 'against impulse'),
    'running_mu': ('running μ', 'hit'),
    'harmonics': ('|mobility|', 'against frequency', 'odd harmonics'),
    'trials': ('force [N]', 'velocity [mm/s]', 'against time'),
    'hit': ('force [N]', 'velocity [mm/s]', 'measured − model'),
    'mobility': ('mobility', 'real', 'imaginary', 'magnitude', 'phase', 'against frequency'),
    'receptance': ('receptance', 'real', 'imaginary', 'magnitude', 'phase', 'against frequency'),
    'coherence': ('coherence γ²', '|mobility|', 'hits (min to max', 'against frequency'),
    'model_mobility': ('mobility', 'measured and model', 'against frequency'),
}
HOSTILE_TITLE = '<script>alert(1)</script>'
HOSTILE_NAME = '"><img src=x onerror=alert(1)>'


def expected_alt_words(name, impact_ids):
    """The words figure `name` (e.g. hit_003, mobility_low) must name in its alt text.

    A hit's figure is named by its position in the session and titled by its impact id,
    impact_ids[position].
    """
    if name in ALT_WORDS:
        return ALT_WORDS[name]
    kind, _, which = name.rpartition('_')
    if kind == 'hit':
        return (*ALT_WORDS[kind], f'hit {impact_ids[int(which)]} ')
    return (*ALT_WORDS[kind], f'level {which}')


def analyzed_ids(inputs):
    """The impact ids `fmm analyze --json` gives the hits of inputs, in session order."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(['analyze', *inputs, '--json', '--paper-levels']) == 0
    return [impact['impact_id'] for impact in json.loads(out.getvalue())['impacts']]


def assert_nothing_complained(seen):
    assert seen.console == [], seen.console
    assert seen.page_errors == [], seen.page_errors
    assert seen.failed_requests == [], seen.failed_requests
    assert seen.dialogs == [], seen.dialogs


@pytest.fixture(scope='module')
def session(tmp_path_factory):
    report = write_csv_session(tmp_path_factory.mktemp('session'))
    assert report['code'] == 0
    return report, visit(report['out'] / 'index.html')


def test_the_report_renders_without_a_complaint(session):
    report, seen = session
    assert_nothing_complained(seen)
    assert seen.title == 'Impact session report'
    for heading in (
        'Session',
        'Hits',
        'Force levels, impulse and linearity',
        'Friction coefficient and model',
        'Force and velocity',
        'Frequency response functions',
    ):
        assert f'\n{heading}\n' in seen.body_text, heading
    assert re.search(r'μ = 0\.11[0-9]+ ± [0-9.]+ fitted to 6 impacts', seen.body_text)
    assert seen.tag_counts.get('script', 0) == 0


def test_every_figure_loads_at_the_size_of_its_png_file(session):
    report, seen = session
    pngs = {path.stem: path for path in report['out'].glob('*.png')}
    assert len(pngs) == 29  # the figures test_report expects of this session
    assert sorted(image.figure_id for image in seen.images) == sorted(
        f'fig-{name}' for name in pngs
    )
    for image in seen.images:
        with Image.open(pngs[image.figure_id.removeprefix('fig-')]) as png:
            size = png.size
        assert image.complete and image.natural_width > 0, image.figure_id
        assert (image.natural_width, image.natural_height) == size, image.figure_id


def test_every_figure_has_an_alt_text_saying_what_it_shows(session):
    report, seen = session
    ids = analyzed_ids(report['inputs'])
    for image in seen.images:
        name = image.figure_id.removeprefix('fig-')
        alt = image.alt or ''
        assert len(alt.split()) >= 8 and '.png' not in alt, (name, alt)
        missing = [word for word in expected_alt_words(name, ids) if word not in alt]
        assert missing == [], f'{name}: alt text {alt!r} lacks {missing}'


def test_a_hostile_title_and_file_name_are_shown_as_text_never_run(tmp_path):
    """Markup in the title and in an input's file name (shown in the inputs, the hit table,
    and the hit figure's title, so in its alt text) must reach the reader as the same text."""
    hit = impact_record(1000.0, rng=3, duration_s=DURATION_S)
    source = tmp_path / f'{HOSTILE_NAME}.csv'
    write_impact_csv(source, hit.force_n, hit.velocity_m_s, RATE_HZ)
    out = tmp_path / 'report'
    title = f'{HOSTILE_TITLE} {HOSTILE_NAME}'
    assert (
        main(
            [
                'report',
                str(source),
                '-o',
                str(out),
                '--paper-levels',
                '--title',
                title,
                '--dpi',
                str(TEST_DPI),
            ]
        )
        == 0
    )
    seen = visit(out / 'index.html')
    assert_nothing_complained(seen)  # an <img src=x> that ran would fail to load, then alert
    assert seen.title == title
    assert seen.body_text.startswith(f'{title}\n')  # the <h1>
    assert f'{HOSTILE_NAME}.csv' in seen.body_text
    figures = len(list(out.glob('*.png')))
    assert seen.tag_counts.get('script', 0) == 0
    assert seen.tag_counts['img'] == seen.tag_counts['figure'] == figures
    assert all(image.figure_id for image in seen.images)
    hit_alt = next(image.alt for image in seen.images if image.figure_id == 'fig-hit_000')
    assert f'{HOSTILE_NAME}.csv' in hit_alt
    # One hit: its level's coherence is not drawn as a flat 1; the page and the figure say why.
    assert 'Coherence is not drawn: level medium has one hit' in seen.body_text
    coherence = next(i.alt for i in seen.images if i.figure_id == 'fig-coherence_medium')
    assert 'coherence needs two hits: level medium has one' in coherence


def test_each_hit_is_folded_under_a_line_and_opens_to_its_figure(session):
    """The per-hit figures made the page 45,000 pixels long: each is now a <details>."""
    report, seen = session
    hits = [image for image in seen.images if image.figure_id.startswith('fig-hit_')]
    assert len(hits) >= 7
    assert seen.tag_counts['details'] == seen.tag_counts['summary'] == len(hits)
    first = analyzed_ids(report['inputs'])[0]
    assert re.search(rf'hit {first} · \w+ · accepted · peak [0-9.]+ N, impulse', seen.body_text)
    assert 'rejected: double_hit' in seen.body_text
    opened = seen.height_open_px - seen.height_px
    assert opened > 0.5 * sum(image.natural_height for image in hits), (seen.height_px, opened)


def test_level_names_flagged_files_and_a_damaged_bag_with_markup_stay_text(tmp_path):
    """The page of test_report_escaping (markup in level names, in the name of a file whose
    hit the fit leaves out, in a damaged bag's name and problems) in a real browser."""
    code, out = escaping.hostile_session(tmp_path)
    assert code == 1
    seen = visit(out / 'index.html')
    assert_nothing_complained(seen)
    assert seen.tag_counts.get('script', 0) == 0 and seen.title == escaping.HOSTILE
    assert seen.tag_counts['img'] == len(list(out.glob('*.png')))
    name = escaping.HOSTILE_NAME
    for text in (escaping.HOSTILE_LEVEL, f'{name}2.csv: clipped', f'{name}bag'):
        assert text in seen.body_text
