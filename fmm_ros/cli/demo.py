"""`fmm demo`: the main job, a simulated rig session end to end through the ROS 2 graph."""

import argparse
import json
import sys
from datetime import datetime
from pathlib import Path

from fmm_ros.cli import options
from fmm_ros.core.physics.rig import PlantRun
from fmm_ros.core.settings import setting_of
from fmm_ros.errors import BadInputError
from fmm_ros.ros.settings import NodeSettings


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add `fmm demo`."""
    parser = subparsers.add_parser(
        'demo',
        help='run a simulated rig session through the ROS 2 node graph',
        description='hammer_sim, rig_sim, analyzer, fitter and recorder in one process: the '
        "paper's three levels, N hits each, recorded to a bag; then the fit "
        'service. Prints per-level impulse and peak receptance, R^2 of magnitude '
        'against impulse, and the fitted mu against the plant mu.',
    )
    options.add_setting(parser, NodeSettings, 'hits_per_level')
    options.add_setting(
        parser,
        NodeSettings,
        'rate_factor',
        default=100.0,
        help='speed-up against real time (the graph runs x500 if asked)',
    )
    options.add_output(
        parser,
        'output folder (default runs/demo_<date>_<time>)',
        metavar='DIR',
    )
    options.add_json(parser, 'one object')
    options.add_setting(parser, PlantRun, 'mu', flag='--plant-mu')
    parser.add_argument(
        '--plant-effect',
        action='append',
        default=[],
        metavar='TERM',
        help='hide a model term in the plant, e.g. stribeck:mu_static_excess=0.02 (repeatable)',
    )
    options.add_setting(parser, NodeSettings, 'seed')
    parser.add_argument(
        '--no-report',
        action='store_true',
        help='skip the HTML report written from the bag afterwards',
    )
    parser.add_argument(
        '--params-file',
        type=Path,
        default=None,
        help='ROS parameter YAML for the nodes (default: their defaults)',
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the session, write summary.json next to the bag, print the summary."""
    from fmm_ros.ros.demo import SessionConfig, run_demo_session  # imports rclpy: only when run

    for name in ('hits_per_level', 'rate_factor'):
        item, value = setting_of(NodeSettings, name), getattr(args, name)
        if not item.limits[0] <= value <= item.limits[1]:
            raise BadInputError(
                f'{item.option} must be in [{item.limits[0]:g}, {item.limits[1]:g}], got {value}'
            )
    out = args.output or Path('runs') / datetime.now().strftime('demo_%Y%m%d_%H%M%S')
    if (out / 'bag').exists():
        raise BadInputError(
            f'{out / "bag"} exists: choose another --output (nothing is overwritten)'
        )
    config = SessionConfig(
        out_dir=out,
        hits_per_level=args.hits_per_level,
        rate_factor=args.rate_factor,
        plant_mu=args.plant_mu,
        plant_effects=tuple(args.plant_effect),
        seed=args.seed,
        params_file=args.params_file,
        report=not args.no_report,
    )
    log = (lambda _: None) if args.json else (lambda line: print(line, file=sys.stderr))
    result = run_demo_session(config, progress=log)
    summary = result.as_json()
    (out / 'summary.json').write_text(json.dumps(summary, indent=2))
    if args.json:
        print(json.dumps(summary))
    else:
        print(_text(result, out))
    return 0 if result.fit_success and result.hits_reported == result.hits_sent else 1


def _text(result, out: Path) -> str:
    """The ten-second summary."""
    from fmm_ros.core import results_schema as schema
    from fmm_ros.core.results_schema import format_with_uncertainty as pm

    impulse, spread, receptance, natural = (
        schema.IMPULSE,
        schema.STD_IMPULSE,
        schema.LEVEL_PEAK_RECEPTANCE,
        schema.LEVEL_NATURAL_FREQUENCY,
    )
    lines = [
        f'{"level":<8}{"hits":>5}{schema.label(impulse, ascii=True):>20}'
        f'{schema.label(receptance, ascii=True):>20}{schema.label(natural, ascii=True):>10}'
    ]
    for level in result.levels:
        lines.append(
            f'{level["name"]:<8}{level[schema.COUNT.name]:>5}'
            f'{level[schema.MEAN_IMPULSE.name]:>12.3f} +- {level[spread.name]:<5.3f}'
            f'{receptance.shown(level[receptance.name]):>20.3f}'
            f'{level[natural.name]:>10.2f}'
        )
    error = (result.mu - result.plant_mu) / result.plant_mu * 100
    lines += [
        f'R^2 of peak |X/F| against impulse: {result.r2:.4f}',
        f'hits: {result.hits_sent} sent, {result.hits_reported} reported, '
        f'{result.hits_accepted} accepted',
        (
            f'mu: {pm(result.mu, result.friction.mu_stderr, schema.ASCII_PM)} fitted, '
            f'{result.plant_mu:.4f} in the plant ({error:+.2f} %)'
            if result.friction
            else f'mu: not fitted ({result.fit_message})'
        ),
        _live_mu(result.running_mu),
        f'model diagnosis: {result.missing_effect or "-"} ({result.diagnosis})',
        f'{result.signal_s:.0f} s of signal in {result.wall_s:.1f} s '
        f'(x{result.signal_s / result.wall_s:.0f} real time); fit {result.fit_s:.1f} s, '
        f'diagnosis {result.diagnose_s:.1f} s',
        f'bag: {result.bag}',
        *(f'  {line}' for line in result.ledger.values()),
        'health (/diagnostics):',
        *(
            f'  {status["level"]:<5} {status["name"]}: {status["message"]}'
            for status in result.health
        ),
        f'summary: {out / "summary.json"}',
    ]
    if result.report:
        lines.append(f'report: {result.report}')
    return '\n'.join(lines)


def _live_mu(running: list[dict]) -> str:
    """How the live mu converged: after the first hit, after each level's hits, at the end."""
    if not running:
        return 'live mu: none published'
    shown = [running[0]] + [e for e in running[1:] if e['count'] % 10 == 0 or e is running[-1]]
    from fmm_ros.core.results_schema import ASCII_PM, format_with_uncertainty

    steps = ', '.join(
        f'{format_with_uncertainty(e["mu"], e["mu_stderr"], ASCII_PM)} ({e["count"]})'
        for e in shown
    )
    return f'live mu (after n hits): {steps}; one mu: p = {running[-1]["consistency_p_value"]:.2g}'
