"""`fmm simulate`: run the friction oscillator from an initial condition or a force record.

Examples (the paper's Fig. 2 oscillator; an FMM response to a recorded hit)::

    fmm simulate --x0-m 0.003 --mu 0.1 --mass-kg 1 --stiffness-n-per-m 5000
                 --damping-n-s-per-m 0 --normal-force-n 9.81 --duration-s 1 --json
    fmm simulate --force-csv hit.csv -o response.csv
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

from fmm_ros.cli import options
from fmm_ros.constants import SAMPLE_RATE_HZ
from fmm_ros.core.physics.rig import SIMULATED_DURATION_S, PlantRun
from fmm_ros.errors import BadInputError

if TYPE_CHECKING:
    import numpy as np

FORCE_COLUMNS = ('time_s', 'force_n')
OUT_COLUMNS = ('time_s', 'force_n', 'displacement_m', 'velocity_m_s')


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `simulate` subcommand."""
    parser = subparsers.add_parser(
        'simulate',
        help='simulate the Coulomb-friction oscillator (paper Eqs. 1-3)',
        description="Simulate m x'' + c x' + k x + mu N sgn(x') = f(t) with the stick rule, "
        'from an initial displacement/velocity and/or a measured force record '
        '(linear between samples). Rig flags default to the FMM.',
    )
    options.add_setting(parser, PlantRun, 'x0_m')
    options.add_setting(parser, PlantRun, 'v0_m_s')
    parser.add_argument(
        '--force-csv',
        type=Path,
        metavar='FILE',
        help='force record with columns time_s,force_n (uniform time step); '
        'without it there is no applied force',
    )
    options.add_setting(parser, PlantRun, 'mu')
    options.add_rig(parser)
    options.add_setting(parser, PlantRun, 'duration_s')
    options.add_setting(parser, PlantRun, 'sample_rate_hz')
    options.add_setting(parser, PlantRun, 'integrator')
    options.add_json(parser, 'the summary')
    options.add_output(
        parser,
        'write time_s,force_n,displacement_m,velocity_m_s to this CSV file',
        metavar='CSV',
    )
    parser.set_defaults(func=run)


def read_force_csv(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(time_s, force_n) from a CSV with header time_s,force_n; ValueError naming the problem."""
    import numpy as np

    with open(path, encoding='utf-8') as stream:
        header = [name.strip() for name in stream.readline().split(',')]
        if tuple(header) != FORCE_COLUMNS:
            raise BadInputError(
                f'{path}: expected the header {",".join(FORCE_COLUMNS)}, got {",".join(header)!r}'
            )
        try:
            table = np.loadtxt(stream, delimiter=',', ndmin=2)
        except ValueError as error:
            raise BadInputError(f'{path}: {error}') from None
    if table.shape[1] != 2 or table.shape[0] < 2:
        raise BadInputError(f'{path}: need at least two rows of time_s,force_n')
    return table[:, 0], table[:, 1]


def run(args: argparse.Namespace) -> int:
    """Simulate as the flags say, print the summary, optionally write the record."""
    import numpy as np

    from fmm_ros.core._checks import time_base
    from fmm_ros.core.physics.model import record_length, simulate

    rig = options.rig_from_args(args)
    start_s = 0.0
    if args.force_csv is not None:
        time_s, force = read_force_csv(args.force_csv)
        rate = time_base(time_s, f'{args.force_csv}: time_s').sample_rate_hz
        if args.sample_rate_hz is not None and not math.isclose(
            args.sample_rate_hz, rate, rel_tol=1e-6
        ):
            raise BadInputError(
                f'--sample-rate-hz {args.sample_rate_hz:g} does not match the '
                f"force record's {rate:.6g} Hz"
            )
        start_s = float(time_s[0])
        if args.duration_s is not None:
            n = record_length(args.duration_s, rate)
            force = np.concatenate((force[:n], np.zeros(max(0, n - force.size))))
    else:
        rate = SAMPLE_RATE_HZ if args.sample_rate_hz is None else args.sample_rate_hz
        duration = SIMULATED_DURATION_S if args.duration_s is None else args.duration_s
        force = np.zeros(record_length(duration, rate))
    sim = simulate(
        force,
        rate,
        rig=rig,
        mu=args.mu,
        x0_m=args.x0_m,
        v0_m_s=args.v0_m_s,
        integrator=args.integrator,
    )
    summary = {
        'final_position_m': float(sim.displacement_m[-1]),
        'rest_time_s': start_s + sim.rest_time_s if sim.at_rest else None,
        'natural_frequency_hz': rig.natural_frequency_hz,
        'damping_ratio': rig.damping_ratio,
        'peak_velocity_m_s': float(np.max(np.abs(sim.velocity_m_s))),
    }
    if args.output is not None:
        table = np.column_stack((start_s + sim.time_s, force, sim.displacement_m, sim.velocity_m_s))
        np.savetxt(
            args.output,
            table,
            delimiter=',',
            header=','.join(OUT_COLUMNS),
            comments='',
            fmt='%.10g',
        )
    if args.json:
        print(json.dumps(summary))
    else:
        rest = (
            'still sliding at the end'
            if summary['rest_time_s'] is None
            else f'at rest from {summary["rest_time_s"]:.4f} s'
        )
        print(
            f'natural frequency {summary["natural_frequency_hz"]:.4f} Hz, '
            f'damping ratio {100 * summary["damping_ratio"]:.4f} %'
        )
        print(f'final position    {1e3 * summary["final_position_m"]:.6f} mm ({rest})')
        print(f'peak velocity     {summary["peak_velocity_m_s"]:.6g} m/s')
        if args.output is not None:
            print(f'wrote {force.size} samples to {args.output}')
    return 0
