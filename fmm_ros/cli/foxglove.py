"""`fmm foxglove`: serve a running graph's live topics to Foxglove (opt in), until Ctrl-C.

Starts the live node (force and velocity decimated to stamped points a plot can draw) and the
foxglove_server node (the Foxglove SDK's WebSocket server) in one process beside a running
rig, on the shell's ROS_DOMAIN_ID. In Foxglove: Open connection, Foxglove WebSocket,
ws://127.0.0.1:8765; then Layouts, Import from file, config/foxglove/fmm_rig_layout.json.
"""

import argparse

from fmm_ros.cli import options
from fmm_ros.errors import BadInputError
from fmm_ros.ros.settings import NodeSettings


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add `fmm foxglove`."""
    parser = subparsers.add_parser(
        'foxglove',
        help='serve the live topics to Foxglove over WebSocket (needs a running ROS graph)',
        description=__doc__.split('\n\n', 1)[1],
    )
    options.add_setting(parser, NodeSettings, 'host')
    options.add_setting(parser, NodeSettings, 'port', default=8765)
    parser.add_argument(
        '--no-live',
        action='store_true',
        help='do not start a live node (one already runs in the graph)',
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Serve until Ctrl-C, SIGTERM or SIGHUP."""
    from rclpy.parameter import Parameter  # rclpy only when serving

    from fmm_ros.ros.launch import run_in_process

    if not 0 <= args.port <= 65535:
        raise BadInputError(f'--port {args.port} is not a TCP port (0 to 65535)')
    nodes = ('foxglove_server',) if args.no_live else ('live', 'foxglove_server')
    overrides = {
        'foxglove_server': [
            Parameter('host', value=args.host),
            Parameter('port', value=args.port),
        ]
    }
    run_in_process(nodes, None, overrides)
    return 0
