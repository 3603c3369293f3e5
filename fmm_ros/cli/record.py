"""`fmm record BAG`: record live topics to a rosbag2 bag (the recorder node, from the CLI)."""

import argparse
from pathlib import Path

from fmm_ros.cli import options
from fmm_ros.constants import RECORDED_TOPICS
from fmm_ros.errors import BadInputError
from fmm_ros.ros.settings import NodeSettings


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add `fmm record`."""
    parser = subparsers.add_parser(
        'record',
        help='record live topics to a bag (needs a running ROS graph)',
        description='Run the recorder node until Ctrl-C: raw subscriptions on the topics, '
        'stored as received in a rosbag2 bag (MCAP by default), flushed every '
        'second so a crash loses at most that much. On ROS_DOMAIN_ID.',
    )
    parser.add_argument('bag', type=Path, help='bag directory to create (must not exist)')
    parser.add_argument(
        '--topics',
        nargs='+',
        metavar='TOPIC',
        default=list(RECORDED_TOPICS),
        help='topics to record (default: the fmm topics)',
    )
    options.add_setting(parser, NodeSettings, 'storage')
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Record until Ctrl-C, then close the bag."""
    from rclpy.parameter import Parameter  # rclpy only when recording

    from fmm_ros.ros.common import run_node
    from fmm_ros.ros.nodes.recorder import Recorder

    if args.bag.exists():
        raise BadInputError(f'{args.bag} exists: choose a new bag path (nothing is overwritten)')
    overrides = [
        Parameter('bag_path', value=str(args.bag)),
        Parameter('topics', value=list(args.topics)),
        Parameter('storage', value=args.storage),
    ]
    run_node(lambda: Recorder(parameter_overrides=overrides), [])
    return 0
