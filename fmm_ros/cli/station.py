"""`fmm station`: the operator's page beside a running rig (the `station` node).

Starts the station node in this process on the shell's ROS_DOMAIN_ID, as
`ros2 run fmm_ros station` would, with the options below as its parameters; Ctrl-C stops it.
Unset options keep the node's defaults (or the params file's): the page is then
http://127.0.0.1:8080/.
"""

from __future__ import annotations

import argparse

from fmm_ros.cli import options
from fmm_ros.ros.settings import NodeSettings, StationSettings


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `station` subcommand."""
    parser = subparsers.add_parser(
        'station',
        help='the live page of a running rig: hits as they land, judged by the operator',
        description=__doc__.split('\n\n', 1)[1],
    )
    # Unset, each keeps the node's default (or the params file's).
    unset = {'default': None}
    options.add_setting(parser, NodeSettings, 'host', **unset)
    options.add_setting(parser, NodeSettings, 'port', **unset)
    options.add_setting(parser, StationSettings, 'judge_mode', **unset)
    options.add_setting(
        parser, StationSettings, 'judge_function', metavar='MODULE:FUNCTION', **unset
    )
    parser.add_argument(
        '--params-file', default=None, help='ROS parameter YAML (its station: section)'
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the station node until a stop signal."""
    from fmm_ros.ros.nodes.station import main

    ros_args = ['--ros-args']
    if args.params_file:
        ros_args += ['--params-file', args.params_file]
    for name in ('host', 'port', 'judge_mode', 'judge_function'):
        value = getattr(args, name)
        if value is not None:
            ros_args += ['-p', f'{name}:={value}']
    return main(ros_args)
