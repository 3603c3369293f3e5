"""Reports: the page builds from a session, every figure is a valid PNG it references,
rejected hits are in the table, nothing in a figure is clipped, and the paper figures build.
The fast path (own layout, reused hit figure, traces drawn per pixel column) draws what the
plain one would."""

import base64
import contextlib
import html.parser
import io
import re

import matplotlib.image
import numpy as np
import pytest
from PIL import Image

from fmm_ros.cli import main
from fmm_ros.constants import FORCE, FORCE_TOPIC, VELOCITY, VELOCITY_TOPIC
from fmm_ros.core.physics.model import simulate
from fmm_ros.core.signal.analysis import analyze_impact
from fmm_ros.core.signal.records import ImpactRecord, write_impact_csv
from fmm_ros.io.bags import BagWriter
from fmm_ros.report import build_report
from fmm_ros.report import html as report_html
from fmm_ros.report.paper import build_paper_report
from fmm_ros.report.plotting import (
    envelope,
    new_figure,
    odd_harmonics,
    pixel_envelope,
    plot_trace,
    png_bytes,
)
from fmm_ros.report.session_figures import HitFigures
from fmm_ros.sim.excitation import hammer_pulse, impact_record
from fmm_ros.sim.hidden_effects import hidden_effect_case
from fmm_ros.sim.session import simulated_session
from fmm_ros.workflows import (
    FrictionResult,
    ModelOverlay,
    SessionOptions,
    impact_ids,
    overlay_of,
    process_records,
)

pytestmark = pytest.mark.slow

PNG_SIGNATURE = b'\x89PNG\r\n\x1a\n'
RATE_HZ = 10_000.0
# Long enough for the FMM to come to rest after the hardest hit (about 3.4 s) plus the 0.5 s
# the unsettled check looks at; short enough to keep the suite fast.
DURATION_S = 4.5
TEST_DPI = 40
# Peak forces of the simulated session: two hits per paper level, and one beyond the force
# sensor's range (clipped, and out of every level's tolerance).
PEAKS_N = {
    '00_low': 440.0,
    '01_low': 470.0,
    '02_medium': 990.0,
    '03_medium': 1020.0,
    '04_high': 1440.0,
    '05_high': 1460.0,
    '07_overload': 1600.0,
}
FULL_SCALE_N = 1550.0


@contextlib.contextmanager
def clipping_checked():
    """Check every figure the page renders: all its artists must lie inside the figure."""
    clipped = []
    render = report_html.png_bytes

    def checked(figure, dpi):
        data = render(figure, dpi)
        box = figure.get_tightbbox()
        width, height = figure.get_size_inches()
        tolerance = 1.5 / dpi  # inches: anti-aliasing may spill a pixel
        if (
            box.x0 < -tolerance
            or box.y0 < -tolerance
            or box.x1 > width + tolerance
            or box.y1 > height + tolerance
        ):
            clipped.append((figure.get_suptitle(), box.bounds, (width, height)))
        return data

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(report_html, 'png_bytes', checked)
        yield clipped


def write_double_hit(path, seed):
    """A medium hit with a 300 N hammer bounce 0.1 s later: the double_hit flag."""
    hit = impact_record(1000.0, rng=seed, duration_s=DURATION_S)
    force = hit.force_n + hammer_pulse(300.0, 2e-3, RATE_HZ, DURATION_S, start_s=0.2)
    velocity = simulate(force, RATE_HZ).velocity_m_s
    velocity = velocity + np.random.default_rng(seed).normal(0.0, 1e-5, velocity.size)
    write_impact_csv(path, force, velocity, RATE_HZ)


def write_csv_session(folder):
    """A session written as per-impact CSV files in folder, reported by `fmm report` (mu
    fitted) into folder/report."""
    for seed, (name, peak) in enumerate(PEAKS_N.items()):
        hit = impact_record(peak, rng=seed, duration_s=DURATION_S)
        write_impact_csv(folder / f'{name}.csv', hit.force_n, hit.velocity_m_s, RATE_HZ)
    write_double_hit(folder / '06_double.csv', seed=99)
    out = folder / 'report'
    inputs = sorted(str(path) for path in folder.glob('*.csv'))
    with clipping_checked() as clipped:
        code = main(
            [
                'report',
                *inputs,
                '-o',
                str(out),
                '--paper-levels',
                '--force-full-scale-n',
                str(FULL_SCALE_N),
                '--dpi',
                str(TEST_DPI),
            ]
        )
    return {
        'code': code,
        'out': out,
        'inputs': inputs,
        'clipped': clipped,
        'page': (out / 'index.html').read_text(encoding='utf-8'),
    }


@pytest.fixture(scope='module')
def csv_session(tmp_path_factory):
    return write_csv_session(tmp_path_factory.mktemp('session'))


class _HitTable(html.parser.HTMLParser):
    """Rows of the page's hit table as (css class, [cell texts])."""

    def __init__(self):
        super().__init__()
        self.rows, self._inside, self._cell = [], False, None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == 'table' and attrs.get('id') == 'hit-table':
            self._inside = True
        elif self._inside and tag == 'tr':
            self.rows.append((attrs.get('class', ''), []))
        elif self._inside and tag in ('td', 'th'):
            self._cell = ''

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data

    def handle_endtag(self, tag):
        if self._inside and tag in ('td', 'th'):
            self.rows[-1][1].append(self._cell)
            self._cell = None
        elif tag == 'table':
            self._inside = False


def hit_rows(page):
    parser = _HitTable()
    parser.feed(page)
    header, *rows = parser.rows
    return header[1], [(css, dict(zip(header[1], cells, strict=True))) for css, cells in rows]


def check_figures(out, page, expected):
    """Every expected figure is a readable PNG, linked from the page and embedded byte for byte."""
    pngs = {path.stem: path for path in out.glob('*.png')}
    assert set(pngs) == set(expected)
    embedded = dict(
        re.findall(
            r'<figure id="fig-([^"]+)">'
            r'<img src="data:image/png;base64,([A-Za-z0-9+/=]+)"',
            page,
        )
    )
    assert set(embedded) == set(expected)
    for name, path in pngs.items():
        data = path.read_bytes()
        assert data.startswith(PNG_SIGNATURE), name
        with Image.open(path) as image:
            image.verify()
        pixels = matplotlib.image.imread(path)
        assert pixels.ndim == 3 and min(pixels.shape[:2]) > 50, name
        assert pixels.std() > 0.01, f'{name} is blank'
        assert f'href="{name}.png"' in page
        assert base64.b64decode(embedded[name]) == data, f'{name}: embedded PNG differs'


def test_report_from_csv_session_has_every_figure(csv_session):
    assert csv_session['code'] == 0
    levels = ('low', 'medium', 'high')
    expected = {
        'impulses',
        'linearity',
        'levels_receptance',
        'harmonics',
        'friction',
        'running_mu',
        *(
            f'{kind}_{level}'
            for kind in ('trials', 'mobility', 'receptance', 'coherence', 'model_mobility')
            for level in levels
        ),
        *(f'hit_{number:03d}' for number in range(len(csv_session['inputs']))),
    }
    check_figures(csv_session['out'], csv_session['page'], expected)


def test_f_n_and_units_are_the_same_in_every_table_figure_and_the_cli(csv_session, capsys):
    """One f_n per level (the analysis's) in the level table and the harmonics figure; the
    receptance in mm/N in the report's tables and in fmm analyze's text alike."""
    page = csv_session['page']
    table = dict(
        re.findall(
            r'<tr><td class="text">(low|medium|high)</td>(?:<td>[^<]*</td>){3}<td>([0-9.]+)</td>',
            page,
        )
    )
    alt = re.search(r'<figure id="fig-harmonics"><img [^>]*alt="([^"]+)"', page)[1]
    drawn = re.findall(r'f_n = ([0-9.]+) Hz', alt)
    assert len(table) == 3 and drawn == [table[level] for level in ('low', 'medium', 'high')]
    assert main(['analyze', *csv_session['inputs'], '--paper-levels']) == 0
    text = capsys.readouterr().out
    assert '|X/F| [mm/N]' in text
    cli_levels = {
        line.split()[0]: (line.split()[3], line.split()[4])
        for line in text.splitlines()
        if line.split()[:1] in (['low'], ['medium'], ['high']) and len(line.split()) == 5
    }
    report_levels = dict(
        re.findall(
            r'<tr><td class="text">(low|medium|high)</td>(?:<td>[^<]*</td>){4}<td>([0-9.]+)</td>',
            page,
        )
    )
    for level, (receptance_mm_n, natural_hz) in cli_levels.items():
        assert float(receptance_mm_n) == pytest.approx(float(report_levels[level]), rel=1e-3)
        assert natural_hz == table[level]


def test_nothing_in_a_figure_is_clipped(csv_session):
    assert csv_session['clipped'] == []


def test_rejected_hits_are_in_the_table_with_their_flags(csv_session):
    _, rows = hit_rows(csv_session['page'])
    by_file = {row['source']: (css, row) for css, row in rows}
    assert len(rows) == len(csv_session['inputs'])
    css, double = by_file['06_double.csv']
    assert (css, double['verdict'], double['flags']) == ('rejected', 'rejected', 'double_hit')
    css, overload = by_file['07_overload.csv']
    assert css == 'rejected' and overload['flags'] == 'clipped, out_of_tolerance'
    accepted = [name for name, (css, row) in by_file.items() if row['verdict'] == 'accepted']
    assert sorted(accepted) == [f'{name}.csv' for name in PEAKS_N if name != '07_overload']
    assert all(css == '' for name, (css, _) in by_file.items() if name in accepted)
    assert 'double_hit</b>: ' in csv_session['page'] and 'clipped</b>: ' in csv_session['page']


def test_mu_is_fitted_over_the_accepted_hits_and_its_model_leaves_only_noise(csv_session):
    """The session was simulated with mu = 0.113: the fit finds it, and the fitted model driven
    by each measured force leaves only the sensor noise."""
    page = csv_session['page']
    fitted = re.search(r'μ = ([0-9.]+) ± ([0-9.]+) fitted to (\d+) impacts at once', page)
    assert fitted is not None
    mu, stderr, count = float(fitted[1]), float(fitted[2]), int(fitted[3])
    assert count == len(PEAKS_N) - 1  # every hit but the overload; the double hit is rejected
    assert abs(mu - 0.113) < max(5 * stderr, 2e-4)
    per_impact = re.findall(r'<td>[0-9.]+</td><td>(0\.1[0-9]+) ± [0-9.]+</td>', page)
    assert len(per_impact) == count
    assert all(abs(float(value) - 0.113) < 1e-3 for value in per_impact)
    header, rows = hit_rows(page)
    column = 'rms(measured − model) [mm/s]'
    assert column in header
    for _, row in rows:
        if row['source'] != '06_double.csv':
            # Velocity noise 0.01 mm/s plus the measured force's noise driving the model.
            assert float(row[column]) < 0.1, row


def test_report_from_a_recorded_session_bag_shows_the_hit_over_a_lost_batch(tmp_path):
    """A bag of one hit per level, one force batch lost inside the last hit."""
    session = simulated_session(1, spacing_s=5.0, seed=4)
    bag = tmp_path / 'session'
    lost = (int(session.hit_start_indices[2]) // 500 + 4) * 500
    with BagWriter(bag) as writer:
        for start in range(0, session.force_n.size, 500):
            if start != lost:
                writer.write_sample_batch(
                    FORCE_TOPIC,
                    session.force_n[start : start + 500],
                    quantity=FORCE,
                    sample_rate_hz=session.sample_rate_hz,
                    first_sample_index=start,
                )
            writer.write_sample_batch(
                VELOCITY_TOPIC,
                session.velocity_m_s[start : start + 500],
                quantity=VELOCITY,
                sample_rate_hz=session.sample_rate_hz,
                first_sample_index=start,
            )
    out = tmp_path / 'report'
    with clipping_checked() as clipped:
        assert (
            main(
                [
                    'report',
                    str(bag),
                    '-o',
                    str(out),
                    '--paper-levels',
                    '--window-s',
                    '4.5',
                    '--fit-initial-position',
                    '--dpi',
                    str(TEST_DPI),
                ]
            )
            == 0
        )
    page = (out / 'index.html').read_text(encoding='utf-8')
    header, rows = hit_rows(page)
    assert [row['source'].split('@')[0] for _, row in rows] == ['session'] * 3
    assert [(css, row['level'], row['flags']) for css, row in rows[:2]] == [
        ('', 'low', '-'),
        ('', 'medium', '-'),
    ]
    assert rows[2][0] == 'rejected' and 'gap' in rows[2][1]['flags'].split(', ')
    # In one continuous recording the second hit finds the rig where friction stopped the
    # first; with that start fitted the model leaves only noise (0.01 mm/s) there too. A
    # record with missing samples cannot drive the model, and says so.
    residuals = [row['rms(measured − model) [mm/s]'] for _, row in rows]
    assert float(residuals[0]) < 0.05 and float(residuals[1]) < 0.05 and residuals[2] == '-'
    starts = re.findall(r'± [0-9.]+</td><td>(-?[0-9.]+)</td></tr>', page)
    assert len(starts) == 2 and abs(float(starts[0])) < 0.005 and 0.01 < abs(float(starts[1])) < 0.4
    check_figures(
        out,
        page,
        {
            'impulses',
            'linearity',
            'levels_receptance',
            'harmonics',
            *(
                f'{kind}_{level}'
                for kind in ('trials', 'mobility', 'receptance', 'coherence', 'model_mobility')
                for level in ('low', 'medium')
            ),
            'hit_000',
            'hit_001',
            'hit_002',
            'friction',
            'running_mu',
        },
    )
    assert clipped == []


def test_diagnosis_names_the_hidden_effect_and_shows_the_gap_shrink(tmp_path):
    """Three hits with a Stribeck effect hidden at 2.5 times the velocity noise (the diagnose
    workflow's proof data), reported with --diagnose."""
    case = hidden_effect_case('stribeck', np.random.default_rng([8, 1]), ratio=2.5, duration_s=6.0)
    inputs = []
    for index, record in enumerate(case.records):
        inputs.append(str(tmp_path / f'hit{index}.csv'))
        write_impact_csv(inputs[-1], record.force_n, record.velocity_m_s, record.sample_rate_hz)
    out = tmp_path / 'report'
    # The proof data's velocity noise (0.1 mm/s) is the default rest threshold: widen it, or
    # every record would be flagged unsettled.
    with clipping_checked() as clipped:
        assert (
            main(
                [
                    'report',
                    *inputs,
                    '-o',
                    str(out),
                    '--no-fit',
                    '--diagnose',
                    '--rest-velocity-m-s',
                    '1e-3',
                    '--dpi',
                    str(TEST_DPI),
                ]
            )
            == 0
        )
    page = (out / 'index.html').read_text(encoding='utf-8')
    assert clipped == []
    named = re.search(r'Missing effects: (\w+)\. Gap .*? ([0-9.e-]+) → ([0-9.e-]+);', page)
    assert named is not None and named[1] == 'stribeck'
    assert float(named[3]) <= 0.5 * float(named[2])
    table = page[page.index('<th class="text">candidate effect</th>') :]
    candidates = re.findall(r'<tr><td class="text">(\w+)</td>', table[: table.index('</table>')])
    # the seven terms, and mu_drift: a candidate from three hits on
    assert len(candidates) == 8 and candidates[0] == 'stribeck' and 'mu_drift' in candidates
    assert 'stribeck.mu_static_excess' in page
    for name in ('diagnosis_residuals', 'diagnosis_mobility', 'diagnosis_friction_map'):
        assert (out / f'{name}.png').read_bytes().startswith(PNG_SIGNATURE)
        assert f'href="{name}.png"' in page


def test_all_rejected_session_still_reports_and_says_why_mu_is_not_fitted(tmp_path, capsys):
    hit = impact_record(1000.0, rng=3, duration_s=DURATION_S)
    write_impact_csv(tmp_path / 'clipped.csv', hit.force_n, hit.velocity_m_s, RATE_HZ)
    out = tmp_path / 'report'
    with clipping_checked() as clipped_figures:
        code = main(
            [
                'report',
                str(tmp_path / 'clipped.csv'),
                '-o',
                str(out),
                '--force-full-scale-n',
                '900',
                '--dpi',
                str(TEST_DPI),
            ]
        )
    assert code == 1  # the page is written, but mu could not be fitted
    # The hit's id is its trigger's time on the session's axis: the file's first, at 0 ms.
    record = ImpactRecord(hit.force_n, hit.velocity_m_s, RATE_HZ)
    refusal = f'no clean impact to fit: impact {impact_ids([record])[0]} ('
    assert f'cannot fit mu: {refusal}' in capsys.readouterr().err
    text = (out / 'index.html').read_text(encoding='utf-8')
    _, rows = hit_rows(text)
    assert [(css, row['flags']) for css, row in rows] == [('rejected', 'clipped')]
    assert 'No level has an accepted hit' in text
    assert f'No friction fit: {refusal}' in text
    check_figures(out, text, {'hit_000'})
    assert clipped_figures == []


def test_a_session_of_records_with_a_given_mu_is_analysed_and_drawn(tmp_path):
    """Records in hand (as the demo holds them), a given mu: process_records, then the page."""
    hit = impact_record(1000.0, rng=3, duration_s=DURATION_S)
    record = ImpactRecord(
        hit.force_n, hit.velocity_m_s, RATE_HZ, force_full_scale_n=900.0, source='clipped.csv'
    )
    session = process_records([record], SessionOptions(mu=0.113))
    page = build_report(session, tmp_path, dpi=TEST_DPI)
    text = page.read_text(encoding='utf-8')
    header, rows = hit_rows(text)
    assert [(css, row['flags']) for css, row in rows] == [('rejected', 'clipped')]
    assert float(rows[0][1]['rms(measured − model) [mm/s]']) < 0.05
    assert 'The model of Eq. 3 with given μ = 0.113' in text
    check_figures(tmp_path, text, {'hit_000'})


def test_model_overlay_is_the_noise_free_plant_driven_by_the_conditioned_force():
    hit = impact_record(1000.0, rng=5, duration_s=DURATION_S)
    record = ImpactRecord(hit.force_n, hit.velocity_m_s, RATE_HZ)
    truth = hit.simulation.velocity_m_s
    given = ModelOverlay(0.113, 'given')
    assert given.label == 'model, given μ = 0.113'
    # Only the force noise inside the hit (0.05 N over ~20 samples) separates them.
    assert np.max(np.abs(given.velocity_m_s(record, 0) - truth)) < 1e-3 * np.max(np.abs(truth))
    # A fitted start position moves the model; other impacts still start at 0.
    summary = FrictionResult(
        0.113,
        1e-5,
        given.rig,
        (0, 1),
        (0.113, 0.113),
        (1e-5, 1e-5),
        initial_positions_m=(2e-4, 0.0),
    )
    moved = overlay_of(summary)
    assert moved.source == 'fitted'
    assert np.max(np.abs(moved.velocity_m_s(record, 0) - truth)) > 1e-3
    np.testing.assert_array_equal(moved.velocity_m_s(record, 1), given.velocity_m_s(record, 0))
    # Gaps cannot drive it.
    gapped = ImpactRecord(
        np.where(np.arange(record.force_n.size) == 9000, np.nan, record.force_n),
        record.velocity_m_s,
        RATE_HZ,
    )
    assert given.velocity_m_s(gapped, 0) is None
    with pytest.raises(ValueError, match='one value per impact'):
        FrictionResult(0.113, 1e-5, given.rig, (0, 1), (0.113,), (1e-5,))


def test_paper_report_reproduces_figs_2_to_10(tmp_path):
    with clipping_checked() as clipped:
        page = build_paper_report(tmp_path, dpi=TEST_DPI)
    text = page.read_text(encoding='utf-8')
    check_figures(
        tmp_path,
        text,
        {
            'fig2_free_vibration_3mm',
            'fig3_free_vibration_1mm',
            'fig4_final_vs_initial',
            'fig5_pulse_durations',
            'fig6_pulse_spectra',
            'fig7_pulse_receptance',
            'fig8_friction_time',
            'fig9_friction_spectra',
            'fig10_friction_receptance',
        },
    )
    assert clipped == []
    # The rest positions the paper quotes for Figs. 2 and 3. From 1 mm the swing shrinks by
    # 2 x_lim = 0.392 mm each half cycle: 1, -0.608, 0.215, then rest at 0.177 mm exactly;
    # the paper's Euler run gave 0.176.
    assert 'comes to rest at -0.139 mm (paper: -0.139 mm)' in text
    assert 'comes to rest at 0.177 mm (paper: 0.176 mm)' in text


def test_cli_refuses_paper_with_inputs_and_nothing_to_report(tmp_path, capsys):
    assert main(['report', '--paper', str(tmp_path / 'a.csv'), '-o', str(tmp_path)]) == 2
    assert main(['report', '-o', str(tmp_path)]) == 2
    errors = capsys.readouterr().err
    assert 'takes no INPUT' in errors and 'or --paper' in errors


def test_a_report_written_again_in_its_folder_leaves_no_stale_figure(tmp_path):
    """A second, smaller report in the same folder removes its predecessor's extra figures
    and nothing the user put there."""
    from matplotlib.figure import Figure

    from fmm_ros.report.html import Page

    (tmp_path / 'notes.png').write_bytes(b'not ours')
    first = Page(tmp_path, 'first')
    for name in ('hit_001', 'hit_002'):
        first.figure(name, Figure(figsize=(2, 2)), name)
    first.write()
    second = Page(tmp_path, 'second')
    second.figure('hit_001', Figure(figsize=(2, 2)), 'hit_001')
    second.write()
    assert sorted(path.name for path in tmp_path.glob('*.png')) == ['hit_001.png', 'notes.png']
    assert 'hit_002' not in (tmp_path / 'index.html').read_text()


def test_model_overlay_refuses_negative_mu():
    with pytest.raises(ValueError, match='mu must not be negative'):
        ModelOverlay(-0.1, 'given')


def test_envelope_keeps_every_bin_extreme_and_gaps():
    rng = np.random.default_rng(0)
    y = rng.normal(size=100_000)
    y[50_000:50_100] = np.nan
    x = np.arange(y.size) * 1e-4
    xs, ys = envelope(x, y, max_points=1000)
    assert xs.size == 1000 and np.all(np.diff(xs) >= 0)
    assert np.nanmax(ys) == np.nanmax(y) and np.nanmin(ys) == np.nanmin(y)
    short_x, short_y = envelope(x[:500], y[:500], max_points=1000)
    assert np.array_equal(short_x, x[:500]) and np.array_equal(short_y, y[:500])
    gap = envelope(x, np.where(np.arange(y.size) < 50_000, y, np.nan), max_points=1000)[1]
    assert np.isnan(gap[-1]) and np.isfinite(gap[0])


def test_odd_harmonics_are_the_odd_multiples_from_three():
    assert [n for n, _ in odd_harmonics(2.2, 20.0)] == [3, 5, 7, 9]
    assert [n for n, _ in odd_harmonics(2.2, 19.0)] == [3, 5, 7]
    assert odd_harmonics(2.2, 20.0)[0][1] == pytest.approx(6.6)
    assert odd_harmonics(float('nan'), 20.0) == []


def test_pixel_envelope_keeps_each_pixel_columns_extremes():
    """Against a brute-force min and max over the samples of each pixel column."""
    rng = np.random.default_rng(2)
    x = np.cumsum(rng.uniform(0.5, 1.5, 50_000)) * 1e-4
    y = rng.normal(size=x.size)
    y[20_000:20_900] = np.nan  # a gap wider than a column stays a gap
    view, width_px = (0.5, 4.0), 300.0
    xs, ys = pixel_envelope(x, y, view, width_px)
    inside = np.flatnonzero((x >= view[0]) & (x <= view[1]))
    kept = slice(inside[0] - 1, inside[-1] + 2)  # one sample beyond each edge
    column = np.floor((x[kept] - view[0]) * width_px / (view[1] - view[0]))
    columns = np.unique(column)
    assert xs.size == ys.size == 2 * columns.size and np.all(np.diff(xs) >= 0)
    assert xs[0] == x[kept][0] and xs[-1] == x[kept][-1]
    with np.errstate(invalid='ignore'), contextlib.suppress(RuntimeWarning):
        for k, value in enumerate(columns):
            samples = y[kept][column == value]
            if np.isnan(samples).all():
                assert np.isnan(ys[2 * k]) and np.isnan(ys[2 * k + 1])
            else:
                assert (ys[2 * k], ys[2 * k + 1]) == (np.nanmin(samples), np.nanmax(samples))
    assert np.isnan(ys).any()
    short = pixel_envelope(x[:400], y[:400], (x[0], x[399]), width_px)
    assert np.array_equal(short[1], y[:400])


def test_a_trace_line_is_drawn_at_the_pixel_columns_of_its_axes():
    """Two points a column at whatever dpi, the one-sample spike drawn to its full height."""
    rng = np.random.default_rng(1)
    x = np.arange(200_000) * 1e-4
    y = np.sin(2 * np.pi * 0.5 * x) + rng.normal(0.0, 0.05, x.size)
    y[123_457] = 3.0
    counts = []
    for dpi in (50, 100):
        figure, (ax,) = new_figure()
        line = plot_trace(ax, x, y, color='black', linewidth=0.8)
        pixels = matplotlib.image.imread(io.BytesIO(png_bytes(figure, dpi)))[..., :3].mean(axis=2)
        drawn_x, drawn_y = line.get_data()
        counts.append(drawn_x.size)
        assert drawn_x.size <= 2 * (ax.bbox.width + 2)
        assert drawn_y.max() == 3.0 and drawn_y.min() == y.min()
        # Inside the frame, the spike's column is inked up to the pixel row of y = 3.
        spike_x, spike_y = ax.transData.transform((x[123_457], 3.0))
        frame_top = int(np.ceil(pixels.shape[0] - ax.bbox.y1)) + 2
        column = pixels[frame_top:, int(spike_x) - 1 : int(spike_x) + 2].min(axis=1)
        inked = np.flatnonzero(column < 0.5) + frame_top
        assert abs(inked.min() - (pixels.shape[0] - spike_y)) <= 2
    assert 1.8 < counts[1] / counts[0] < 2.2


def test_a_reused_hit_figure_draws_what_a_fresh_one_draws():
    """Nothing of one hit (data, colour, limits, ticks, legend, rows) leaks into the next."""
    model = ModelOverlay(0.113, 'given')
    hits = []
    for number, peak in enumerate((1450.0, 440.0)):
        hit = impact_record(peak, rng=number, duration_s=DURATION_S)
        record = ImpactRecord(hit.force_n, hit.velocity_m_s, RATE_HZ, source=f'{number}.csv')
        hits.append(
            (record, analyze_impact(record, impact_id=number), model.velocity_m_s(record, number))
        )

    def drawn(figures, number, with_model, colour):
        record, result, velocity = hits[number]
        figure = figures.draw(
            record,
            result,
            model_velocity_m_s=velocity if with_model else None,
            model_label=model.label,
            colour=colour,
        )
        return figure, matplotlib.image.imread(io.BytesIO(png_bytes(figure, TEST_DPI)))

    reused = HitFigures()
    drawn(reused, 0, True, 'tab:green')
    drawn(reused, 0, False, 'tab:gray')
    for with_model in (True, False):
        (figure, again), (_, fresh) = (
            drawn(figures, 1, with_model, 'tab:orange') for figures in (reused, HitFigures())
        )
        assert again.shape == fresh.shape
        # Sub-pixel shifts of the layout change a few edge pixels by a few levels; a leaked
        # colour or artist changes a percent of the image by far more.
        assert (np.abs(again - fresh).max(axis=2) > 0.02).mean() < 1e-3
        # And what both draw is this hit: every axes' y range hugs its lines (5 % margins).
        for ax in figure.axes:
            ys = np.concatenate([line.get_ydata() for line in ax.lines])
            low, high = ax.get_ylim()
            span = np.nanmax(ys) - np.nanmin(ys)
            assert low <= np.nanmin(ys) and high >= np.nanmax(ys) and high - low < 1.2 * span
        legend = figure.axes[1].get_legend()
        if with_model:
            measured = legend.get_lines()[0]
            assert measured.get_color() == figure.axes[1].lines[0].get_color() == 'tab:orange'
        else:
            assert legend is None


def test_layout_keeps_long_labels_apart_and_inside_with_a_figure_legend():
    figure, axes = new_figure(2, 2, title='a title')
    for number, ax in enumerate(axes):
        ax.plot([0, 1], [0, 123456789 * (number + 1)], label=f'line {number}')
        ax.ticklabel_format(axis='y', style='plain', useOffset=False)
        ax.set_ylabel('a long label\nin two lines [unit]')
        ax.set_xlabel('x [unit]')
        ax.set_title(f'axes {number}')
    figure.legend(loc='lower center', ncols=4)
    png_bytes(figure, TEST_DPI)
    renderer = figure.canvas.get_renderer()
    width, height = figure.bbox.width, figure.bbox.height
    boxes = [ax.get_tightbbox(renderer) for ax in axes]
    for box in [*boxes, figure.legends[0].get_window_extent(renderer)]:
        assert box.x0 >= 0 and box.y0 >= 0 and box.x1 <= width and box.y1 <= height
    for first, box in enumerate(boxes):
        for other in boxes[first + 1 :]:
            assert not box.overlaps(other)
    legend_top = figure.legends[0].get_window_extent(renderer).y1
    assert all(box.y0 > legend_top for box in boxes)
    title = figure.texts[0].get_window_extent(renderer)
    assert all(box.y1 < title.y0 for box in boxes)


def test_layout_refuses_a_figure_too_small_for_its_labels():
    figure, axes = new_figure(4, 1, height_in=1.5)
    for ax in axes:
        ax.set_xlabel('x [unit]')
    with pytest.raises(ValueError, match='too small|labels'):
        png_bytes(figure, TEST_DPI)
