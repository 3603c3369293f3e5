"""Model flags of the subcommands that run the model (simulate, fit, report, diagnose)."""

import argparse

from fmm_ros.core.physics.rig import FMM_RIG, Rig


def add_rig_arguments(parser: argparse.ArgumentParser) -> None:
    """--mass-kg, --stiffness-n-per-m, --damping-n-s-per-m, --normal-force-n (FMM defaults)."""
    parser.add_argument(
        '--mass-kg',
        type=float,
        default=FMM_RIG.mass_kg,
        help=f'moving mass m [kg] (default {FMM_RIG.mass_kg})',
    )
    parser.add_argument(
        '--stiffness-n-per-m',
        type=float,
        default=FMM_RIG.stiffness_n_per_m,
        help=f'spring constant k [N/m] (default {FMM_RIG.stiffness_n_per_m:g})',
    )
    parser.add_argument(
        '--damping-n-s-per-m',
        type=float,
        default=FMM_RIG.damping_n_s_per_m,
        help=f'viscous damping c [N*s/m] (default {FMM_RIG.damping_n_s_per_m})',
    )
    parser.add_argument(
        '--normal-force-n',
        type=float,
        default=FMM_RIG.normal_force_n,
        help=f'normal force N [N] (default 0.680 kg x 9.81 m/s^2 = {FMM_RIG.normal_force_n:.4f})',
    )


def add_fit_freedom_arguments(parser: argparse.ArgumentParser) -> None:
    """--fit-damping and --[no-]fit-initial-position: what a friction fit frees besides mu."""
    parser.add_argument(
        '--fit-damping',
        action='store_true',
        help='fit the viscous damping c too (otherwise c is the rig constant)',
    )
    add_initial_position_argument(
        parser,
        'fit where the rig rested before each hit (default: friction leaves it off centre '
        'after the previous one); --no-fit-initial-position starts each at x = 0',
    )


def add_initial_position_argument(parser: argparse.ArgumentParser, help_text: str) -> None:
    """--fit-initial-position (the default) / --no-fit-initial-position."""
    parser.add_argument(
        '--fit-initial-position',
        action=argparse.BooleanOptionalAction,
        default=True,
        help=help_text,
    )


def rig_from_args(args: argparse.Namespace) -> Rig:
    """The Rig the rig flags describe (ValueError naming a bad constant)."""
    return Rig(
        mass_kg=args.mass_kg,
        stiffness_n_per_m=args.stiffness_n_per_m,
        damping_n_s_per_m=args.damping_n_s_per_m,
        normal_force_n=args.normal_force_n,
    )
