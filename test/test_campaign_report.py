"""The campaign report in a real browser: it renders without a complaint, every figure loads,
and markup in the table's values, session ids, notes and the title is shown as text, never run."""

import csv

import pytest
from browser import visit
from PIL import Image
from test_report_browser import HOSTILE_NAME, HOSTILE_TITLE, assert_nothing_complained

from fmm_ros.cli import main
from fmm_ros.core.signal.records import write_impact_csv
from fmm_ros.sim.excitation import impact_record

pytestmark = pytest.mark.slow

DURATION_S = 8.0
NOTE = '<b onmouseover=alert(2)>bold</b> & "quoted"'


def test_hostile_table_values_ids_and_notes_are_shown_as_text(tmp_path):
    rows = [['session', 'id', 'lubricant', 'normal_force_n', 'notes']]
    for number, (lubricant, mu) in enumerate(
        (
            (HOSTILE_TITLE, 0.113),
            (HOSTILE_TITLE, 0.114),
            (HOSTILE_NAME, 0.10),
            (HOSTILE_NAME, 0.101),
        )
    ):
        folder = tmp_path / f'session_{number}'
        folder.mkdir()
        for hit in range(2):
            record = impact_record(1000.0, rng=10 * number + hit, mu=mu, duration_s=DURATION_S)
            write_impact_csv(folder / f'hit_{hit}.csv', record.force_n, record.velocity_m_s, 1e4)
        rows.append([folder.name, f'{HOSTILE_NAME}{number}', lubricant, '6.6708', NOTE])
    table = tmp_path / 'campaign.csv'
    with open(table, 'w', newline='', encoding='utf-8') as stream:
        csv.writer(stream).writerows(rows)
    out = tmp_path / 'report'
    title = f'{HOSTILE_TITLE} campaign'
    code = main(
        [
            'campaign',
            str(table),
            '-o',
            str(out),
            '--serial',
            '--by',
            'lubricant',
            '--trend',
            'normal_force_n',
            '--paper-levels',
            '--title',
            title,
            '--dpi',
            '60',
        ]
    )
    assert code == 0
    seen = visit(out / 'index.html')
    assert_nothing_complained(seen)  # an injected <img src=x> would fail to load, then alert
    assert seen.title == title
    assert seen.body_text.startswith(f'{title}\n')
    assert seen.tag_counts.get('script', 0) == 0 and seen.tag_counts.get('b', 0) == 0
    for number in range(4):
        assert f'{HOSTILE_NAME}{number}' in seen.body_text
    assert NOTE in seen.body_text and HOSTILE_TITLE in seen.body_text
    pngs = {path.stem: path for path in out.glob('*.png')}
    assert sorted(image.figure_id for image in seen.images) == sorted(f'fig-{n}' for n in pngs)
    for image in seen.images:
        with Image.open(pngs[image.figure_id.removeprefix('fig-')]) as png:
            assert (image.natural_width, image.natural_height) == png.size, image.figure_id
        assert len((image.alt or '').split()) >= 6, image.figure_id
    conditions = next(i.alt for i in seen.images if i.figure_id == 'fig-conditions')
    assert 'lubricant against μ [-]' in conditions
