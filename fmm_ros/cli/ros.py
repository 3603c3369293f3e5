"""`fmm ros`: look at and use a running fmm graph from the venv, where there is no `ros2`.

The venv's ROS 2 comes from PyPI wheels, which have no `ros2` command line; in a sourced lab
workspace use `ros2` itself. These do the few things a lab needs, through rclpy
(`fmm_ros.ros.introspect`), on the shell's ROS_DOMAIN_ID:

    fmm ros nodes                      ros2 node list
    fmm ros topics [-t]                ros2 topic list [-t]
    fmm ros services [-t]              ros2 service list [-t]
    fmm ros call fit [--fit-damping]   ros2 service call /fmm/fit_friction ...
    fmm ros call diagnose              ros2 service call /fmm/diagnose_model ...
    fmm ros param describe NODE [P]    ros2 param describe NODE P (and its value)
    fmm ros run NODE [ARGS...]         ros2 run fmm_ros NODE ARGS...
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from fmm_ros.cli import options
from fmm_ros.constants import DIAGNOSE_SERVICE, FIT_SERVICE
from fmm_ros.core.identify.spec import FitSpec
from fmm_ros.errors import BadInputError


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add `fmm ros` and its commands."""
    parser = subparsers.add_parser(
        'ros',
        help='list the graph, call the services, describe parameters (no ros2 needed)',
        description=__doc__.split('\n\n', 1)[1],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument(
        '--discovery-s',
        type=float,
        default=2.0,
        help='time to let discovery find the graph before asking it [s] (default 2)',
    )
    commands = parser.add_subparsers(dest='ros_command', metavar='COMMAND', required=True)
    nodes = commands.add_parser('nodes', help='the nodes of the graph', parents=[common])
    nodes.set_defaults(func=run_list)
    for name in ('topics', 'services'):
        listing = commands.add_parser(name, help=f'the {name} of the graph', parents=[common])
        listing.add_argument('-t', '--types', action='store_true', help='show their types')
        listing.set_defaults(func=run_list)

    call = commands.add_parser('call', help='call the fitter node services', parents=[common])
    call.add_argument('service', choices=('fit', 'diagnose'))
    call.add_argument(
        '--impact-id',
        type=int,
        action='append',
        default=[],
        dest='impact_ids',
        help='an impact to use (repeatable; default: every accepted impact the fitter holds)',
    )
    fit = call.add_argument_group("fit (both mu ends 0: the fitter's own search range)")
    options.add_setting(fit, FitSpec, 'fit_damping')
    options.add_range_setting(
        fit, FitSpec, 'mu_bounds', ('--mu-min', '--mu-max'), default=(0.0, 0.0)
    )
    options.add_setting(fit, FitSpec, 'misfit')
    call.add_argument('--name', help='the service name (default: /fmm/fit_friction, ...)')
    call.add_argument(
        '--timeout-s', type=float, default=600.0, help='longest wait for the answer [s]'
    )
    options.add_json(call, 'the answer')
    call.set_defaults(func=run_call)

    param = commands.add_parser('param', help="a node's parameters", parents=[common])
    param.add_argument('action', choices=('describe',))
    param.add_argument('node', help='node name, e.g. /fitter')
    param.add_argument('names', nargs='*', metavar='PARAM', help='parameters (default: all)')
    param.set_defaults(func=run_param)

    node = commands.add_parser('run', help='start a node of fmm_ros, as ros2 run fmm_ros NODE')
    node.add_argument('node', help='analyzer, fitter, hammer_sim, rig_sim, daq, recorder, player')
    node.add_argument('node_args', nargs=argparse.REMAINDER, help='its arguments (--ros-args ...)')
    node.set_defaults(func=run_node)


def run_list(args: argparse.Namespace) -> int:
    """Print the graph's nodes, topics or services."""
    from fmm_ros.ros.introspect import GraphProbe  # rclpy: only when asked

    with GraphProbe(discovery_s=args.discovery_s) as probe:
        if args.ros_command == 'nodes':
            lines = probe.nodes()
        else:
            found = probe.topics() if args.ros_command == 'topics' else probe.services()
            lines = [
                f'{name} [{", ".join(types)}]' if args.types else name for name, types in found
            ]
    print('\n'.join(lines))
    return 0


def run_call(args: argparse.Namespace) -> int:
    """Call /fmm/fit_friction or /fmm/diagnose_model; print the answer (exit 1 if refused)."""
    from fmm_interfaces.srv import DiagnoseModel, FitFriction
    from fmm_ros.cli.formats import diagnosis_text, friction_text
    from fmm_ros.ros import msgs
    from fmm_ros.ros.introspect import GraphProbe

    if args.service == 'fit':
        service, name = FitFriction, args.name or FIT_SERVICE
        request = FitFriction.Request(
            impact_ids=args.impact_ids,
            fit_damping=args.fit_damping,
            mu_min=args.mu_min,
            mu_max=args.mu_max,
            misfit=args.misfit,
        )
    else:
        service, name = DiagnoseModel, args.name or DIAGNOSE_SERVICE
        request = DiagnoseModel.Request(impact_ids=args.impact_ids)
    with GraphProbe(discovery_s=args.discovery_s) as probe:
        response = probe.call(service, name, request, args.timeout_s)
    if not response.success:
        if args.json:
            print(json.dumps({'error': response.message}))
        else:
            print(f'fmm ros call: {name} refused: {response.message}', file=sys.stderr)
        return 1
    if args.service == 'fit':
        result = msgs.friction_result(response)
        print(json.dumps(result.to_dict(), indent=2) if args.json else friction_text(result))
    else:
        payload = msgs.diagnose_response_dict(response)
        impacts = len(args.impact_ids) or 'the accepted'
        print(json.dumps(payload, indent=2) if args.json else diagnosis_text(payload, impacts))
    return 0


def run_param(args: argparse.Namespace) -> int:
    """Describe a node's parameters: type, value, description, range, read-only."""
    from fmm_ros.ros.introspect import GraphProbe

    with GraphProbe(discovery_s=args.discovery_s) as probe:
        found = probe.parameters(args.node, args.names)
    for info in found:
        print(f'{info.name} ({info.type}) = {info.value!r}')
        print(f'  {info.description}')
        if info.constraints:
            print(f'  constraints: {info.constraints}')
        if info.read_only:
            print('  read-only: set at start-up only')
    return 0


def run_node(args: argparse.Namespace) -> int:
    """Replace this process by the node's executable, found as ros2 run finds it."""
    from ament_index_python.packages import get_package_prefix

    os.environ.setdefault('AMENT_PREFIX_PATH', sys.prefix)
    directory = Path(get_package_prefix('fmm_ros')) / 'lib' / 'fmm_ros'
    executable = directory / args.node
    if not executable.is_file():
        known = ', '.join(sorted(path.name for path in directory.iterdir() if path.is_file()))
        raise BadInputError(f'fmm_ros has no executable {args.node!r}; it has: {known}')
    os.execv(executable, [str(executable), *args.node_args])
    return 0  # not reached: execv replaces the process
