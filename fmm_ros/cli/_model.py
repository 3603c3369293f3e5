"""What the subcommands that run or fit the model share: rig flags, reporting a refused fit.

Used by simulate, fit, identify-rig (and diagnose, which takes fit's flags).
"""

import argparse
import json
import sys

from fmm_ros.core.fit import FitError
from fmm_ros.core.model import FMM_RIG, Rig


def add_rig_arguments(parser: argparse.ArgumentParser) -> None:
    """--mass-kg, --stiffness-n-per-m, --damping-n-s-per-m, --normal-force-n (FMM defaults)."""
    parser.add_argument('--mass-kg', type=float, default=FMM_RIG.mass_kg,
                        help=f'moving mass m [kg] (default {FMM_RIG.mass_kg})')
    parser.add_argument('--stiffness-n-per-m', type=float, default=FMM_RIG.stiffness_n_per_m,
                        help=f'spring constant k [N/m] (default {FMM_RIG.stiffness_n_per_m:g})')
    parser.add_argument('--damping-n-s-per-m', type=float, default=FMM_RIG.damping_n_s_per_m,
                        help=f'viscous damping c [N*s/m] (default {FMM_RIG.damping_n_s_per_m})')
    parser.add_argument('--normal-force-n', type=float, default=FMM_RIG.normal_force_n,
                        help='normal force N [N] (default 0.680 kg x 9.81 m/s^2 = '
                             f'{FMM_RIG.normal_force_n:.4f})')


def rig_from_args(args: argparse.Namespace) -> Rig:
    """The Rig the rig flags describe (ValueError naming a bad constant)."""
    return Rig(mass_kg=args.mass_kg, stiffness_n_per_m=args.stiffness_n_per_m,
               damping_n_s_per_m=args.damping_n_s_per_m, normal_force_n=args.normal_force_n)


def report_refusal(command: str, failure: FitError, as_json: bool) -> int:
    """Print why the records could not be fitted (JSON on stdout, or a line on stderr); 1.

    Exit status 1 is a verdict on the data (friction or the lifted rig does not explain it),
    kept apart from bad input or flags (2).
    """
    if as_json:
        print(json.dumps({'error': failure.reason, 'message': str(failure),
                          'file': failure.source or None}))
    else:
        print(f'fmm {command}: cannot fit ({failure.reason}): {failure}', file=sys.stderr)
    return 1
