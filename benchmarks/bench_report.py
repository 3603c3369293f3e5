"""Session report: the time of build_report for a 30-hit session, and of each figure type.

Run: .venv/bin/python benchmarks/bench_report.py [--repeats R] [--dpi D] [-o DIR]

A simulated session of ten hits at each of the paper's three levels, one every 33 s as
`fmm demo` records them, is cut into impact records; process_records analyses them and runs the
model with a given mu (Eq. 3 over every hit and FRF; fitting is timed by bench_fit), and
build_report draws the page: both are timed together, as the report's time. Then the same
report the naive way, in the same run: matplotlib's
constrained layout for every figure (a layout pass, the ticks frozen, savefig), and a fresh
Figure for every hit. Last, what each figure type costs both ways (build and render, per
figure), and what the report spends outside its figures (analysis, model, page).
Target: build_report of a 30-hit session <= 6 s on the shared 2-core machine.
"""

import argparse
import collections
import contextlib
import io
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

from results_file import QUICK_HELP, recorded

from fmm_ros.constants import PAPER_MU, REPORT_DPI
from fmm_ros.core.signal.analysis import AnalysisConfig, paper_levels
from fmm_ros.core.signal.capture import capture_impacts
from fmm_ros.report import build_report, session_figures
from fmm_ros.report import html as report_html
from fmm_ros.report.plotting import freeze_ticks
from fmm_ros.sim.session import simulated_session
from fmm_ros.workflows.session import SessionOptions, process_records

TARGET_S = 6.0
HIT_FIGURES = session_figures.HitFigures
ANALYSIS = AnalysisConfig(levels=paper_levels())
FIGURE_TYPES = (
    'impulse_figure',
    'linearity_figure',
    'level_magnitude_figure',
    'level_trials_figure',
    'frf_trials_figure',
    'coherence_figure',
    'frf_overlay_figure',
    'harmonics_figure',
    'friction_figure',
)


def constrained_png(figure, dpi):
    """The naive render: constrained layout, a layout pass to freeze the ticks, savefig."""
    figure.set_layout_engine('constrained')
    figure.set_dpi(dpi)
    figure.draw_without_rendering()
    freeze_ticks(figure)
    buffer = io.BytesIO()
    figure.savefig(buffer, format='png', dpi=dpi, facecolor='white', metadata={'Software': None})
    return buffer.getvalue()


class FreshHitFigures:
    """The naive hit figures: a new Figure for every hit."""

    def draw(self, *args, **kwargs):
        """One hit, in a Figure of its own."""
        return HIT_FIGURES().draw(*args, **kwargs)


@contextlib.contextmanager
def instrumented(naive: bool):
    """Time each figure type inside build_report: {type: [figures, build s, render s]}."""
    cost = collections.defaultdict(lambda: [0, 0.0, 0.0])
    last = ['']

    def timed_build(name, build):
        def run(*args, **kwargs):
            start = time.perf_counter()
            figure = build(*args, **kwargs)
            cost[name][0] += 1
            cost[name][1] += time.perf_counter() - start
            last[0] = name
            return figure

        return run

    render = constrained_png if naive else report_html.png_bytes

    def timed_render(figure, dpi):
        start = time.perf_counter()
        data = render(figure, dpi)
        cost[last[0]][2] += time.perf_counter() - start
        return data

    hits = FreshHitFigures if naive else session_figures.HitFigures
    with contextlib.ExitStack() as stack:
        patch = stack.enter_context(_patched())
        for name in FIGURE_TYPES:
            patch(session_figures, name, timed_build(name, getattr(session_figures, name)))
        patch(hits, 'draw', timed_build('hit (Figs. 18/20/22)', hits.draw))
        patch(session_figures, 'HitFigures', hits)
        patch(report_html, 'png_bytes', timed_render)
        yield cost


@contextlib.contextmanager
def _patched():
    saved = []

    def patch(owner, name, value):
        saved.append((owner, name, getattr(owner, name)))
        setattr(owner, name, value)

    try:
        yield patch
    finally:
        for owner, name, value in reversed(saved):
            setattr(owner, name, value)


def run(records, out: Path, dpi: float, naive: bool):
    """One report (process_records, build_report): its time [s] and each figure type's cost."""
    shutil.rmtree(out, ignore_errors=True)
    with instrumented(naive) as cost:
        start = time.perf_counter()
        session = process_records(records, SessionOptions(analysis=ANALYSIS, mu=PAPER_MU))
        build_report(session, out, dpi=dpi)
        seconds = time.perf_counter() - start
    return seconds, dict(cost)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeats', type=int, default=3)
    parser.add_argument('--dpi', type=float, default=REPORT_DPI)
    parser.add_argument(
        '-o', '--output', type=Path, help='keep the report here (default: a temp dir)'
    )
    parser.add_argument('--quick', action='store_true', help=QUICK_HELP)
    args = parser.parse_args()
    if args.quick:
        args.repeats, args.dpi = 1, 40.0

    session = simulated_session(1 if args.quick else 10)
    records = capture_impacts(session.force_n, session.velocity_m_s, session.sample_rate_hz)
    work = Path(tempfile.mkdtemp(prefix='bench_report_'))
    out = args.output or work / 'report'
    try:
        run(records[:3], work / 'warm', args.dpi, naive=False)  # imports, font cache
        runs = {
            naive: [
                run(records, out if not naive else work / 'naive', args.dpi, naive)
                for _ in range(args.repeats)
            ]
            for naive in (False, True)
        }
    finally:
        shutil.rmtree(work)
    figures = sum(count for count, _, _ in runs[False][0][1].values())
    print(
        f'session: {len(records)} hits ({len(session.hit_levels) // 3} a level), '
        f'{records[0].window_samples / records[0].sample_rate_hz:g} s records at '
        f'{records[0].sample_rate_hz / 1e3:g} kHz, given mu = {PAPER_MU}; {figures} figures '
        f'at {args.dpi:g} dpi; median of {args.repeats} runs\n'
    )
    ours = statistics.median(seconds for seconds, _ in runs[False])
    naive = statistics.median(seconds for seconds, _ in runs[True])
    print(f'{"build_report":58s} {ours:6.2f} s')
    print(
        f'{"naive: constrained layout per figure, a Figure per hit":58s} {naive:6.2f} s '
        f'(x{naive / ours:.1f})'
    )
    print(f'target build_report <= {TARGET_S:g} s: {"met" if ours <= TARGET_S else "NOT met"}\n')

    print(
        f'{"figure type":24s} {"count":>5s} {"ms a figure":>12s} {"naive":>7s} {"ratio":>6s}'
        f'   (build + render)'
    )
    figure_s = {}
    for naive_run in (False, True):
        totals = collections.defaultdict(float)
        for _, cost in runs[naive_run]:
            for name, (_count, build_s, render_s) in cost.items():
                totals[name] += (build_s + render_s) / len(runs[naive_run])
        figure_s[naive_run] = totals
    for name, (count, _, _) in sorted(
        runs[False][0][1].items(), key=lambda item: -figure_s[False][item[0]]
    ):
        mine, theirs = (1e3 * figure_s[flag][name] / count for flag in (False, True))
        print(
            f'{name.removesuffix("_figure"):24s} {count:5d} {mine:12.0f} {theirs:7.0f} '
            f'{theirs / mine:6.1f}'
        )
    outside = [
        statistics.median(
            seconds - sum(b + r for _, b, r in cost.values()) for seconds, cost in runs[flag]
        )
        for flag in (False, True)
    ]
    print(
        f'{"outside the figures (analysis, model, page)":44s} {outside[0]:6.2f} s '
        f'(naive run {outside[1]:.2f} s)'
    )
    return 0


if __name__ == '__main__':
    with recorded('bench_report', quick='--quick' in sys.argv):
        raise SystemExit(main())
