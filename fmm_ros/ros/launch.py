"""Start a whole rig without ros2 launch: in one process (one executor) or one process a node.

The PyPI ROS wheels have no launch system, and a lab may not want one for four nodes. In one
process the nodes share an executor (cheapest: no serialization between processes' copies of
the graph); as separate processes each node is the executable `ros2 run` would start, from
`<prefix>/lib/fmm_ros/`, so this is also how the lab's installed nodes are exercised.
Parameters come from a params file, plus `node.param=value` overrides; each source is told
which of the rig's nodes consume its batches (`wait_for_consumers`), so it holds its first
sample until they are there.

Signals, as a process manager sends them: SIGINT (Ctrl-C), SIGTERM (systemd, docker stop,
ros2 launch's escalation) and SIGHUP (a closed terminal) are handled explicitly, also when
the launcher was started with SIGINT ignored (a script's background job inherits SIG_IGN).
The signal is forwarded to every node; a node still running `SIGTERM_TIMEOUT_S` after its
signal gets SIGTERM, after `SIGKILL_TIMEOUT_S` more SIGKILL, as ros2 launch escalates.
Each node runs in a session of its own (a Ctrl-C reaches it once, through the launcher)
with the parent-death signal set to SIGTERM (Linux prctl), so even a launcher killed with
SIGKILL takes its nodes with it: they close their bags and exit.
"""

import ctypes
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import yaml
from rclpy.parameter import Parameter

from fmm_ros.errors import BadInputError
from fmm_ros.ros.graph import InProcessGraph
from fmm_ros.ros.nodes import CONSUMERS, node_class

SIMULATED_RIG = ('hammer_sim', 'rig_sim', 'analyzer', 'fitter', 'recorder')
REAL_RIG = ('daq', 'analyzer', 'fitter', 'recorder')
STATION = 'station'
"""The operator's page: added to a rig by the launch scripts' --station."""
# Escalation after the forwarded signal, each node's counted from its own, as ros2 launch's
# defaults [s]; each stage of the ordered stop waits at most STAGE_TIMEOUT_S before the next
# is signalled (the simulated rig: three stages, at most 3 + 5 + 4 s in all).
SIGTERM_TIMEOUT_S = 5.0
SIGKILL_TIMEOUT_S = 4.0
STAGE_TIMEOUT_S = 1.5
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
PR_SET_PDEATHSIG = 1  # linux/prctl.h


def consumer_overrides(nodes: Sequence[str]) -> dict[str, list[Parameter]]:
    """`wait_for_consumers` of each source in nodes: the nodes of the rig that take its batches."""
    return {
        source: [
            Parameter(
                'wait_for_consumers', value=[n for n in CONSUMERS[source] if n in nodes] or ['']
            )
        ]
        for source in nodes
        if source in CONSUMERS
    }


def with_wiring(
    nodes: Sequence[str], overrides: dict[str, list[Parameter]]
) -> dict[str, list[Parameter]]:
    """The given overrides after the rig's wiring between its nodes (so a `--set` still wins).

    The wiring: each source's consumer list (`consumer_overrides`), and the analyzer's and
    the fitter's `recorder_bag` set to the recorder's `bag_path` when the overrides give one
    (respawned, they take from that bag the hits they missed while down).
    """
    merged = {name: list(params) for name, params in consumer_overrides(nodes).items()}
    bag = [p.value for p in overrides.get('recorder', []) if p.name == 'bag_path']
    for reader in ('analyzer', 'fitter'):
        if reader in nodes and bag and bag[-1]:
            merged.setdefault(reader, []).append(Parameter('recorder_bag', value=str(bag[-1])))
    for name, params in overrides.items():
        merged.setdefault(name, []).extend(params)
    return merged


class StopSignals:
    """SIGINT, SIGTERM and SIGHUP handled explicitly (SIG_IGN replaced): the first one is kept.

    Use as a context manager; the previous handlers come back on exit.
    """

    def __init__(self) -> None:
        self.received: int | None = None
        self._previous: dict[int, object] = {}

    def __enter__(self) -> 'StopSignals':
        for signum in STOP_SIGNALS:
            self._previous[signum] = signal.signal(signum, self._on_signal)
        return self

    def __exit__(self, *exc_info: object) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)

    def _on_signal(self, signum: int, frame: object) -> None:
        if self.received is None:
            self.received = signum


def parse_overrides(items: Sequence[str], nodes: Sequence[str]) -> dict[str, list[Parameter]]:
    """`node.param=value` strings (value in YAML, e.g. 2.5, [1, 2], true) per node."""
    overrides: dict[str, list[Parameter]] = {name: [] for name in nodes}
    for item in items:
        target, equals, text = item.partition('=')
        node, dot, name = target.partition('.')
        if not (equals and dot and name):
            raise BadInputError(f'override {item!r} is not node.param=value')
        if node not in overrides:
            raise BadInputError(
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
    """All nodes on one executor in this process, on ROS_DOMAIN_ID, until stopped.

    A stop signal or stop() ends it; the graph then tears down in order (the recorder closes
    its bag).
    """
    cli_args = ['--ros-args', '--params-file', str(params_file)] if params_file else None
    domain_id = int(os.environ.get('ROS_DOMAIN_ID', '0'))
    localhost = os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE', '') == 'LOCALHOST'
    with InProcessGraph(domain_id=domain_id, localhost_only=localhost) as graph:
        for name in nodes:
            graph.add(
                node_class(name), cli_args=cli_args, parameter_overrides=overrides.get(name, [])
            )
        with StopSignals() as signals:
            graph.start()
            while not stop() and signals.received is None:
                time.sleep(0.1)


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


def _parent_death_signal() -> Callable[[], None] | None:
    """The preexec function that makes a child die with the launcher (Linux), or None."""
    try:
        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    launcher = os.getpid()

    def preexec() -> None:
        for signum in STOP_SIGNALS:  # the node installs its own; nothing inherited ignored
            signal.signal(signum, signal.SIG_DFL)
        prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
        if os.getppid() != launcher:  # the launcher died before prctl took effect
            os.kill(os.getpid(), signal.SIGTERM)

    return preexec


def start_processes(
    nodes: Sequence[str],
    params_file: Path | None,
    overrides: dict[str, list[Parameter]],
    log_dir: Path | None = None,
) -> list[subprocess.Popen]:
    """One process per node, each given the params file and its overrides.

    Each in a session of its own, and (Linux) terminated when the launcher dies. log_dir:
    each node's output goes to <log_dir>/<node>.log instead of this process's.
    """
    preexec = _parent_death_signal()
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
        log = (log_dir / f'{name}.log').open('ab') if log_dir else None
        processes.append(
            subprocess.Popen(
                node_command(name) + ros_args,
                start_new_session=True,
                preexec_fn=preexec,
                stdout=log,
                stderr=subprocess.STDOUT if log else None,
            )
        )
        if log:
            log.close()  # the child holds its own descriptor
    return processes


def wait_for_log(log_dir: Path, node: str, text: str, timeout_s: float) -> bool:
    """Wait until a node started with `log_dir` has logged text; whether it did in timeout_s.

    For scripts that drive a rig of processes by what its nodes say (a source's start, a
    first report), polling <log_dir>/<node>.log every 0.1 s.
    """
    log = log_dir / f'{node}.log'
    deadline = time.monotonic() + timeout_s
    while not (log.exists() and text in log.read_text(errors='replace')):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.1)
    return True


def stop_order(nodes: Sequence[str]) -> list[list[int]]:
    """Positions of nodes in the order they stop: sources first, then what they feed.

    A consumer stopped after its sources has taken everything they published, so the bag
    ends where the acquisition ended (CONSUMERS says who feeds whom).
    """
    left = set(range(len(nodes)))
    stages = []
    while left:
        fed = {n for k in left if nodes[k] in CONSUMERS for n in CONSUMERS[nodes[k]]}
        stage = sorted(k for k in left if nodes[k] not in fed) or sorted(left)
        stages.append(stage)
        left -= set(stage)
    return stages


def stop_processes(
    processes: Sequence[subprocess.Popen],
    signum: int = signal.SIGINT,
    sigterm_timeout_s: float = SIGTERM_TIMEOUT_S,
    sigkill_timeout_s: float = SIGKILL_TIMEOUT_S,
    nodes: Sequence[str] | None = None,
) -> list[int]:
    """Stop the nodes; their exit codes.

    signum goes to the sources first, then (each stage given up to STAGE_TIMEOUT_S) to what
    they feed, when the node names are known. A node still running sigterm_timeout_s after
    its own signal gets SIGTERM, and SIGKILL sigkill_timeout_s after that, as ros2 launch
    escalates each process on its own clock. Counted from the first signal instead, the
    last stage (analyzer, fitter and recorder, after hammer_sim's and rig_sim's) kept as
    little as 2 s of the 5: a loaded fitter finishing its live fits was killed.
    """
    stages = stop_order(nodes) if nodes else [list(range(len(processes)))]
    signalled: dict[int, float] = {}  # position: when it was last signalled [monotonic s]
    for stage in stages:
        running = [k for k in stage if processes[k].poll() is None]
        for k in running:
            processes[k].send_signal(signum)
            signalled[k] = time.monotonic()
        if len(stages) > 1:
            _wait_all([processes[k] for k in running], STAGE_TIMEOUT_S)
    for escalation, after_s in (
        (signal.SIGTERM, sigterm_timeout_s),
        (signal.SIGKILL, sigkill_timeout_s),
    ):
        for k in sorted(signalled, key=signalled.get):
            try:
                processes[k].wait(max(0.01, signalled[k] + after_s - time.monotonic()))
            except subprocess.TimeoutExpired:
                processes[k].send_signal(escalation)
                signalled[k] = time.monotonic()
    return [process.wait() for process in processes]


def _wait_all(processes: Sequence[subprocess.Popen], timeout_s: float) -> None:
    """Wait until each process ended or timeout_s passed."""
    deadline = time.monotonic() + max(0.0, timeout_s)
    for process in processes:
        try:
            process.wait(max(0.01, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            pass


def run_processes(
    nodes: Sequence[str], params_file: Path | None, overrides: dict[str, list[Parameter]]
) -> int:
    """Separate processes until a stop signal or until one of them exits; 0 if all ended cleanly."""
    with StopSignals() as signals:
        processes = start_processes(nodes, params_file, overrides)
        while signals.received is None and all(process.poll() is None for process in processes):
            time.sleep(0.2)
        for name, process in zip(nodes, processes, strict=True):
            if signals.received is None and process.poll() is not None:
                print(
                    f'{name} exited with status {process.returncode}: stopping the rig',
                    file=sys.stderr,
                )
        codes = stop_processes(processes, signals.received or signal.SIGINT, nodes=nodes)
    clean = (0, -signal.SIGINT, -signal.SIGTERM)
    return 0 if all(code in clean for code in codes) else 1


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
    parser.add_argument(
        '--station',
        action='store_true',
        help='also start the station: the live page on http://127.0.0.1:8080/ '
        '(--set station.port=... to move it)',
    )
    args = parser.parse_args(argv)
    if args.station:
        nodes = (*nodes, STATION)
    if args.params_file is not None and not args.params_file.is_file():
        parser.error(f'--params-file {args.params_file} does not exist')
    try:
        overrides = parse_overrides(args.set, nodes)
    except ValueError as error:
        parser.error(str(error))
    print(
        f'starting {", ".join(nodes)} '
        + ('as separate processes' if args.processes else 'in one process')
        + f' with {args.params_file or "node defaults"}; Ctrl-C, SIGTERM or SIGHUP stops',
        file=sys.stderr,
    )
    overrides = with_wiring(nodes, overrides)
    if args.processes:
        return run_processes(nodes, args.params_file, overrides)
    run_in_process(nodes, args.params_file, overrides)
    return 0
