"""Start a whole rig without ros2 launch: in one process (one executor) or one process a node.

The PyPI ROS wheels have no launch system, and a lab may not want one for four nodes. In one
process the nodes share an executor (cheapest: no serialization between processes' copies of
the graph); as separate processes each node is the executable `ros2 run` would start, from
`<prefix>/lib/fmm_ros/`, so this is also how the lab's installed nodes are exercised.
Parameters come from a params file, plus `node.param=value` overrides.
"""

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import yaml
from rclpy.parameter import Parameter

from fmm_ros.ros.graph import InProcessGraph
from fmm_ros.ros.nodes import node_class

SIMULATED_RIG = ('hammer_sim', 'rig_sim', 'analyzer', 'fitter', 'recorder')
REAL_RIG = ('daq', 'analyzer', 'fitter', 'recorder')


def parse_overrides(items: Sequence[str], nodes: Sequence[str]) -> dict[str, list[Parameter]]:
    """`node.param=value` strings (value in YAML, e.g. 2.5, [1, 2], true) per node."""
    overrides: dict[str, list[Parameter]] = {name: [] for name in nodes}
    for item in items:
        target, equals, text = item.partition('=')
        node, dot, name = target.partition('.')
        if not (equals and dot and name):
            raise ValueError(f'override {item!r} is not node.param=value')
        if node not in overrides:
            raise ValueError(
                f'override {item!r}: no node {node!r} in this rig ({", ".join(nodes)})'
            )
        overrides[node].append(Parameter(name, value=yaml.safe_load(text)))
    return overrides


def run_in_process(
    nodes: Sequence[str],
    params_file: Path | None,
    overrides: dict[str, list[Parameter]],
    stop: Callable[[], bool] = lambda: False,
) -> None:
    """All nodes on one executor in this process, on ROS_DOMAIN_ID, until Ctrl-C or stop()."""
    cli_args = ['--ros-args', '--params-file', str(params_file)] if params_file else None
    domain_id = int(os.environ.get('ROS_DOMAIN_ID', '0'))
    localhost = os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE', '') == 'LOCALHOST'
    with InProcessGraph(domain_id=domain_id, localhost_only=localhost) as graph:
        for name in nodes:
            graph.add(
                node_class(name), cli_args=cli_args, parameter_overrides=overrides.get(name, [])
            )
        graph.start()
        try:
            while not stop():
                time.sleep(0.1)
        except KeyboardInterrupt:
            pass


def node_command(name: str) -> list[str]:
    """How `ros2 run fmm_ros <name>` starts the node: its executable in <prefix>/lib/fmm_ros."""
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    os.environ.setdefault('AMENT_PREFIX_PATH', sys.prefix)
    try:
        executable = Path(get_package_prefix('fmm_ros')) / 'lib' / 'fmm_ros' / name
    except PackageNotFoundError:
        executable = None
    if executable is not None and os.access(executable, os.X_OK):
        return [str(executable)]
    return [sys.executable, '-m', f'fmm_ros.ros.nodes.{name}']


def start_processes(
    nodes: Sequence[str], params_file: Path | None, overrides: dict[str, list[Parameter]]
) -> list[subprocess.Popen]:
    """One process per node, each given the params file and its overrides."""
    processes = []
    for name in nodes:
        ros_args = ['--ros-args']
        if params_file:
            ros_args += ['--params-file', str(params_file)]
        for parameter in overrides.get(name, []):
            ros_args += [
                '-p',
                f'{parameter.name}:={yaml.safe_dump(parameter.value).strip()}'.replace('\n...', ''),
            ]
        processes.append(subprocess.Popen(node_command(name) + ros_args))
    return processes


def stop_processes(processes: Sequence[subprocess.Popen], timeout_s: float = 10.0) -> list[int]:
    """SIGINT every node (as Ctrl-C would), wait, kill what hangs; the exit codes."""
    for process in processes:
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
    deadline = time.monotonic() + timeout_s
    for process in processes:
        try:
            process.wait(max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    return [process.returncode for process in processes]


def run_processes(
    nodes: Sequence[str], params_file: Path | None, overrides: dict[str, list[Parameter]]
) -> int:
    """Separate processes until Ctrl-C or until one of them exits; 0 if all ended cleanly."""
    processes = start_processes(nodes, params_file, overrides)
    try:
        while all(process.poll() is None for process in processes):
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    codes = stop_processes(processes)
    return 0 if all(code in (0, -signal.SIGINT) for code in codes) else 1


def default_params_file() -> Path | None:
    """config/fmm_rig.yaml of the installed package (share/fmm_ros/config), or the checkout's."""
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

    os.environ.setdefault('AMENT_PREFIX_PATH', sys.prefix)
    candidates = [Path(__file__).resolve().parents[1] / 'config' / 'fmm_rig.yaml']
    try:
        candidates.insert(
            0, Path(get_package_share_directory('fmm_ros')) / 'config' / 'fmm_rig.yaml'
        )
    except PackageNotFoundError:
        pass
    return next((path for path in candidates if path.is_file()), None)


def launch_main(nodes: Sequence[str], description: str, argv: Sequence[str] | None = None) -> int:
    """Command line of the launch scripts: params file, overrides, one process or many."""
    import argparse

    parser = argparse.ArgumentParser(description=description)
    parser.add_argument(
        '--params-file',
        type=Path,
        default=default_params_file(),
        help="ROS parameter YAML (default: the package's config/fmm_rig.yaml)",
    )
    parser.add_argument(
        '--set',
        action='append',
        default=[],
        metavar='NODE.PARAM=VALUE',
        help='override one parameter, e.g. hammer_sim.rate_factor=20 (repeatable; VALUE in YAML)',
    )
    parser.add_argument(
        '--processes',
        action='store_true',
        help='one process per node (as ros2 run would start them) instead of '
        'all nodes on one executor in this process',
    )
    args = parser.parse_args(argv)
    if args.params_file is not None and not args.params_file.is_file():
        parser.error(f'--params-file {args.params_file} does not exist')
    try:
        overrides = parse_overrides(args.set, nodes)
    except ValueError as error:
        parser.error(str(error))
    print(
        f'starting {", ".join(nodes)} '
        + ('as separate processes' if args.processes else 'in one process')
        + f' with {args.params_file or "node defaults"}; Ctrl-C stops',
        file=sys.stderr,
    )
    if args.processes:
        return run_processes(nodes, args.params_file, overrides)
    run_in_process(nodes, args.params_file, overrides)
    return 0
