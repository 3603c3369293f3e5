"""The documentation: the site builds without a warning, covers the code, and the prose stays short.

The site build (Sphinx + MyST, `make docs`) is run here as CI runs it, with warnings as
errors, into a temporary folder. Its reference pages are generated from the code, so the
test also checks that every subcommand, node parameter and message field is on them, and
that no page loads anything from the network.
"""

import argparse
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / 'docs'
sys.path.insert(0, str(DOCS / '_ext'))
sys.path.insert(0, str(REPO / 'benchmarks'))

from fmm_reference import parse_interface  # noqa: E402
from results_file import read_section  # noqa: E402

# The README is read in ten minutes; the map stays a map. Counted as `wc -w` counts.
WORD_LIMITS = {'README.md': 1_500, 'ARCHITECTURE.md': 3_000}


@pytest.mark.parametrize('name', sorted(WORD_LIMITS))
def test_readme_and_architecture_stay_within_their_word_limits(name):
    words = len((REPO / name).read_text(encoding='utf-8').split())
    assert words <= WORD_LIMITS[name], f'{name} has {words} words (limit {WORD_LIMITS[name]})'


def _readme() -> str:
    """The README's words, one space apart (a quoted figure may wrap)."""
    return ' '.join((REPO / 'README.md').read_text(encoding='utf-8').split())


def _number(text: str) -> tuple[float, int]:
    """A quoted figure's value and its decimals ('1,713' -> (1713.0, 0))."""
    text = text.replace(',', '')
    return float(text), len(text.partition('.')[2])


# How a measured speed is worded: a rate against real time or a baseline ("1,713x real time",
# "2.5x the time to fill", "x49.6 steady"), a time something takes ("simulates in 0.66 ms",
# "diagnosed in 3.8 s"). A pace the reader sets ("at 100 times real time") is not a figure.
SPEED_FIGURE_PATTERNS = (
    r'\b[\d,.]+x (?:real time|the |on )',
    r'\(x[\d.]+ steady\)',
    r'\b(?:runs|replays|simulates|diagnosed|fitted|takes?) in [\d,.]+ (?:ms|s|µs)\b',
    r'\bkeeps? x\d',
)


def test_the_readme_quotes_no_speed_figure_and_points_to_results_md():
    """Speed figures live in benchmarks/RESULTS.md, which each full benchmark run rewrites; the
    site's benchmarks page says what each script measures. A figure copied into the README
    would go stale with the next run, so the README quotes none and says where they are."""
    readme = _readme()
    quoted = [m.group(0) for p in SPEED_FIGURE_PATTERNS for m in re.finditer(p, readme)]
    assert not quoted, f'the README quotes speed figures {quoted}: point to RESULTS.md instead'
    assert '`benchmarks/RESULTS.md`' in readme
    assert '(docs/reference/benchmarks.md)' in readme
    assert '{fmm-benchmarks}' in (DOCS / 'reference' / 'benchmarks.md').read_text('utf-8')


def test_the_speed_figure_patterns_find_a_quoted_figure():
    """The patterns above catch the wordings a speed figure was quoted with, and leave a pace
    the reader sets alone (so the test above can fail)."""
    quoting = (
        'a session bag replays at 1,713x real time (1.47x the bare read of its messages; '
        '1,150x on one core), one record simulates in 0.66 ms (2.5x the time to fill its '
        'arrays), a session is diagnosed in 3.8 s, and the graph keeps x50 (x49.6 steady).'
    )
    found = [m.group(0) for p in SPEED_FIGURE_PATTERNS for m in re.finditer(p, quoting)]
    assert len(found) == 8, found
    assert not any(
        re.search(p, 'the demo runs at 100 times real time') for p in SPEED_FIGURE_PATTERNS
    )


HELD_OUT_SWEEPS = tuple(
    f'bench_diagnose, held out worlds{seed}' for seed in ('', ', seed 2020', ', seed 2021')
)
"""The RESULTS.md sections of the held-out sweeps the README quotes, seeds 2019-2021."""


def test_the_readme_quotes_the_held_out_sweeps_results_md_holds():
    """Each held-out world's right sessions a seed, the clean sessions, the three-hit drifts,
    and the effects at least their stated size, as the three sweeps in RESULTS.md count them."""
    readme = _readme()
    sections = [read_section(name) for name in HELD_OUT_SWEEPS]
    assert all(sections), HELD_OUT_SWEEPS

    def summed(pattern: str) -> tuple[int, int]:
        pairs = [m for s in sections for m in re.findall(pattern, s)]
        assert len(pairs) == 3 * len(sections), pattern  # three worlds a sweep
        return sum(int(a) for a, _ in pairs), sum(int(b) for _, b in pairs)

    for world in ('events', 'newmark', 'karnopp'):
        quoted = re.search(rf'`{world}` (\d+), (\d+) and (\d+)', readme)
        right = [
            re.search(rf'\*\*{world}\*\*.*?- right: (\d+) of', s, re.DOTALL).group(1)
            for s in sections
        ]
        assert quoted and list(quoted.groups()) == right, (world, right)
    alarms, clean = summed(r'false alarms on clean sessions: (\d+) of (\d+)')
    drifts, drifted = summed(r'- mu drift: named in (\d+) of (\d+)')
    named, stated = summed(r'at least the size their diagnosis said[^:]*: named (\d+) of (\d+)')
    pairs, both = summed(r'both effects at least the size[^:]*: both named in (\d+) of (\d+)')
    for counted, pattern in (
        ((alarms, clean), r'no clean session called anything \(([\d,]+) of ([\d,]+)\)'),
        ((drifts, drifted), r'three-hit drift ([\d,]+) of ([\d,]+)'),
        ((named, stated, pairs, both), r'name ([\d,]+) of ([\d,]+), of the pairs (\d+) of (\d+)'),
    ):
        quoted = re.search(pattern, readme)
        assert quoted and counted == tuple(_number(g)[0] for g in quoted.groups()), pattern


LIMIT_SECTIONS = (
    'bench_diagnose, held out limits at 1.5x [events]',
    'bench_diagnose, held out limits at 1.5x [newmark, karnopp]',
)
"""The RESULTS.md sections of the effects set at 1.5x their stated limit: `events` (7
sessions a kind), `newmark` and `karnopp` (20 each), every held-out world."""
PAIRS_SECTION = 'bench_diagnose, held out worlds [events, newmark, karnopp] (pair)'
"""The RESULTS.md section of the held-out pairs since the physical ranges."""


def test_the_readme_quotes_the_limits_results_md_holds():
    """Per kind over the held-out worlds swept, the effects named at 1.5x the limit a clean
    session stated, those clean sessions, and the pairs with effects under their limit excused."""
    readme = _readme()
    sections = [read_section(name) for name in LIMIT_SECTIONS]
    assert all(sections), LIMIT_SECTIONS
    for multiple in ('1.5',):
        per_kind: dict[str, list[int]] = {}
        lines = [
            kinds
            for section in sections
            for kinds in re.findall(
                rf'named at {multiple}x the stated size, per kind: (.*?); worst', section
            )
        ]
        assert len(lines) == 3, lines  # a line a world
        for kinds in lines:
            for kind, named, total in re.findall(r'([\w ]+?) (\d+) of (\d+)(?:, |$)', kinds):
                counts = per_kind.setdefault(kind.strip(), [0, 0])
                counts[0] += int(named)
                counts[1] += int(total)
        worst = min(per_kind.values(), key=lambda n: n[0] / n[1])
        named, total = (sum(n[i] for n in per_kind.values()) for i in (0, 1))
        quoted = re.search(
            rf'at {re.escape(multiple)}x ([\d,]+) of ([\d,]+) named '
            r'\(the worst kind (\d+) of (\d+)\)',
            readme,
        )
        assert quoted, multiple
        assert tuple(_number(g)[0] for g in quoted.groups()) == (named, total, *worst), multiple
    alarms = [
        re.findall(r'- clean sessions that named anything: (\d+) of (\d+)', s) for s in sections
    ]
    pairs = re.findall(
        r'pairs, each effect under the size its session shows it from excused: '
        r'right in (\d+) of (\d+)',
        read_section(PAIRS_SECTION),
    )
    assert len(pairs) == 3, PAIRS_SECTION
    for counted, pattern in (
        (
            [m for found in alarms for m in found],
            r'clean sessions ([\d,]+) of ([\d,]+) name anything',
        ),
        (pairs, r'pairs, an effect under its stated size excused, (\d+) of (\d+)'),
    ):
        quoted = re.search(pattern, readme)
        summed = tuple(sum(int(m[i]) for m in counted) for i in (0, 1))
        assert quoted and summed == tuple(_number(g)[0] for g in quoted.groups()), pattern


def test_the_held_out_page_quotes_the_sweeps_results_md_holds():
    """The Results table of heldout-validation.md: each row a sweep in RESULTS.md still holds
    (the held-out worlds at three seeds, the tuning worlds at 2019) says its right sessions."""
    page = (DOCS / 'explanation' / 'heldout-validation.md').read_text(encoding='utf-8')
    rows = re.findall(r'^\| (\w+) \| (tuning|held out) \| (\d{4}) \| (\d+) of (\d+) \|', page, re.M)
    checked = 0
    for world, role, seed, right, sessions in rows:
        if role == 'held out':
            name = HELD_OUT_SWEEPS[('2019', '2020', '2021').index(seed)]
        elif seed == '2019':
            name = 'bench_diagnose, tuning worlds'
        else:
            continue  # a tuning world's sweep from when it was held out, since replaced
        swept = re.search(rf'\*\*{world}\*\*.*?- right: (\d+) of (\d+)', read_section(name), re.S)
        assert swept and swept.groups() == (right, sessions), (world, seed, name)
        checked += 1
    assert checked == 9 + 7, checked  # three held-out worlds at three seeds, seven tuning worlds


# A site page is read at one sitting; a page's history belongs to git, not to the page.
PAGE_WORD_LIMIT = 6_000


def test_every_site_page_stays_within_the_page_word_limit():
    long = {
        str(page.relative_to(DOCS)): words
        for page in sorted(DOCS.glob('*/*.md'))
        if (words := len(page.read_text(encoding='utf-8').split())) > PAGE_WORD_LIMIT
    }
    assert not long, f'pages over {PAGE_WORD_LIMIT} words: {long}'


def test_every_page_has_one_title_and_sits_in_a_globbed_folder():
    """The index globs these four folders, so a page anywhere else would be left out."""
    pages = sorted(DOCS.glob('*/*.md'))
    assert {page.parent.name for page in pages} == {
        'tutorials',
        'howto',
        'explanation',
        'reference',
    }
    for page in pages:
        lines = page.read_text(encoding='utf-8').splitlines()
        fence = False
        titles = []
        for line in lines:
            fence ^= line.startswith('```')
            if not fence and line.startswith('# '):
                titles.append(line)
        assert lines[0].startswith('# ') and len(titles) == 1, page


def test_interface_files_parse_into_described_fields():
    """Every field of every .msg and .srv has a comment to show on the reference page."""
    files = sorted((REPO / 'fmm_interfaces').glob('*/*.*'))
    assert {path.suffix for path in files} >= {'.msg', '.srv'}
    for path in files:
        parts = parse_interface(path.read_text(encoding='utf-8'))
        assert len(parts) == (1 if path.suffix == '.msg' else 2), path
        for part in parts:
            for group in part.groups:
                assert group.fields and group.comment, (path, group)


def test_interface_parser_groups_fields_under_their_comment():
    text = (
        '# A message.\n\n# Mean [-] and its error [-].\nfloat64 mu\nfloat64 mu_stderr\n'
        '---\nbool ok\n'
    )
    request, response = parse_interface(text)
    assert request.description == ['A message.']
    assert [(g.comment, g.fields) for g in request.groups] == [
        (['Mean [-] and its error [-].'], ['float64 mu', 'float64 mu_stderr'])
    ]
    assert [(g.comment, g.fields) for g in response.groups] == [([], ['bool ok'])]
    with pytest.raises(ValueError, match='not a field'):
        parse_interface('float64[ mu\n')


@pytest.fixture(scope='module')
def site(tmp_path_factory) -> Path:
    """The site built as `make docs` builds it; the build's own output on failure."""
    out = tmp_path_factory.mktemp('site')
    result = subprocess.run(
        [
            *(sys.executable, '-m', 'sphinx'),
            *('-W', '--keep-going', '-n', '-q', '-b', 'html'),
            *(str(DOCS), str(out)),
        ],
        capture_output=True,
        text=True,
        env={**os.environ, 'MPLBACKEND': 'Agg'},
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-6000:]
    assert not result.stderr.strip(), result.stderr[-6000:]
    return out


def _text(page: Path) -> str:
    """A page's text without its tags."""
    return re.sub(r'<[^>]+>', ' ', page.read_text(encoding='utf-8'))


@pytest.mark.slow
def test_the_site_builds_without_warnings_and_loads_nothing_from_the_network(site):
    pages = sorted(site.rglob('*.html'))
    assert len(pages) > 30
    for page in pages:
        html = page.read_text(encoding='utf-8')
        remote = re.findall(r'<(?:script|link|img)[^>]+(?:src|href)="(?:https?:)?//[^"]+"', html)
        assert not remote, (page, remote)
    for folder in ('tutorials', 'howto', 'explanation', 'reference'):
        for source in (DOCS / folder).glob('*.md'):
            assert (site / folder / f'{source.stem}.html').exists(), source


@pytest.mark.slow
def test_the_reference_covers_every_command_parameter_and_field(site):
    from fmm_ros.cli import build_parser
    from fmm_ros.ros.nodes import NODES, node_module

    cli = _text(site / 'reference' / 'cli.html')
    parser = build_parser()
    commands = next(a for a in parser._actions if a.__class__.__name__ == '_SubParsersAction')
    for name, sub in commands.choices.items():
        assert f'fmm {name}' in cli, name
        for action in sub._actions:
            if action.help == argparse.SUPPRESS:  # deprecated aliases: not documented
                continue
            for flag in action.option_strings:
                assert flag in cli, (name, flag)
    nodes = _text(site / 'reference' / 'nodes.html')
    for name in NODES:
        for param in node_module(name).PARAMS:
            assert param.name in nodes, (name, param.name)
    interfaces = _text(site / 'reference' / 'interfaces.html')
    for path in sorted((REPO / 'fmm_interfaces').glob('*/*.*')):
        assert path.stem in interfaces
        for part in parse_interface(path.read_text(encoding='utf-8')):
            for group in part.groups:
                for field in group.fields:
                    assert field.split()[-1] in interfaces, (path, field)


@pytest.mark.slow
def test_the_gallery_draws_the_papers_figures(site):
    gallery = site / 'auto_examples'
    examples = sorted((DOCS / 'examples').glob('plot_*.py'))
    assert examples
    for example in examples:
        assert (gallery / f'{example.stem}.html').exists(), example
    images = list((site / '_images').glob('sphx_glr_plot_*.png'))
    assert len(images) >= len(examples)
