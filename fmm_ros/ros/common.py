"""What every fmm_ros node shares: the rig's parameters and the `ros2 run` entry point.

The QoS profiles are declared in `fmm_ros.ros.qos` (SAMPLE_QOS and RESULT_QOS are re-exported
here for code that took them from here).
"""

import importlib
import signal
import threading
import time
from collections.abc import Callable

import rclpy
from rclpy.executors import (
    ExternalShutdownException,
    MultiThreadedExecutor,
    SingleThreadedExecutor,
)
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from fmm_ros.core.physics.rig import Rig
from fmm_ros.errors import SourceStartTimeout
from fmm_ros.ros.params import Param, ParamValue, params_from
from fmm_ros.ros.qos import RESULT_QOS, SAMPLE_QOS  # noqa: F401 (re-exported)
from fmm_ros.ros.settings import NodeSettings
from fmm_ros.sim.daq import ChannelChain

# The rig constants of Eq. 3, as parameters (rig_sim simulates with them, the fitter fits
# with them): the Rig's declared settings; defaults are the paper's FMM.
RIG_PARAMS = params_from(Rig)


def shared_params(*names: str, read_only: bool = True, **defaults: ParamValue) -> tuple[Param, ...]:
    """The shared parameters names (`NodeSettings`), with this node's defaults where given."""
    return params_from(NodeSettings(**defaults), names, read_only=read_only)


def chain_params(channel: str, unit: str, suffix: str, offset_limit: float) -> tuple[Param, ...]:
    """A simulated channel's data acquisition chain (`sim.daq.ChannelChain`) as parameters.

    channel: what the descriptions call it; unit and suffix: its SI unit and the names' unit
    suffix ('N' and 'n'); offset_limit: the largest zero error accepted [unit].
    """
    return (
        Param(
            'anti_alias_order',
            0,
            f'Butterworth anti-alias filter of the {channel} channel, order [-] (0: none)',
            limits=(0, 12),
            read_only=True,
        ),
        Param(
            'anti_alias_cutoff_hz',
            4000.0,
            'Its -3 dB frequency [Hz] (below half the sample rate)',
            limits=(1.0, 1e6),
            read_only=True,
        ),
        Param(
            f'offset_{suffix}',
            0.0,
            f'Zero error of the {channel} channel [{unit}]',
            limits=(-offset_limit, offset_limit),
            read_only=True,
        ),
        Param(
            f'drift_{suffix}_per_sqrt_s',
            0.0,
            f'Random-walk drift of that zero: its standard deviation after 1 s [{unit}]',
            limits=(0.0, offset_limit),
            read_only=True,
        ),
        Param(
            f'hum_amplitude_{suffix}',
            0.0,
            f'Mains hum on the {channel} channel, amplitude of the fundamental [{unit}] '
            '(harmonics 2, 3, 5 at 1/2, 1/3, 1/5 of it)',
            limits=(0.0, offset_limit),
            read_only=True,
        ),
        Param('mains_hz', 50.0, 'Mains frequency [Hz]', limits=(10.0, 1000.0), read_only=True),
    )


def chain_from_parameters(config: dict, suffix: str) -> ChannelChain:
    """The ChannelChain the `chain_params` values of a node's config describe."""
    return ChannelChain(
        anti_alias_order=config['anti_alias_order'],
        anti_alias_cutoff_hz=config['anti_alias_cutoff_hz'],
        offset=config[f'offset_{suffix}'],
        drift_per_sqrt_s=config[f'drift_{suffix}_per_sqrt_s'],
        hum_amplitude=config[f'hum_amplitude_{suffix}'],
        mains_hz=config['mains_hz'],
    )


def rig_from_parameters(config: dict) -> Rig:
    """The Rig the RIG_PARAMS values of a node's config describe."""
    return Rig(**{param.name: config[param.name] for param in RIG_PARAMS})


# The signals a process manager sends a node: Ctrl-C, systemd / docker stop / ros2 launch's
# escalation, and a closed terminal or a launcher's reload.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
# A consumer asked to stop first takes the batches already queued for it: until none came
# for DRAIN_QUIET_S, at most DRAIN_MAX_S [s]. (The launcher stops the sources first.)
DRAIN_QUIET_S = 0.1
DRAIN_MAX_S = 1.0


def run_node(
    node_factory: Callable[[], Node],
    args: list[str] | None = None,
    *,
    threads: int = 1,
    stop_poll_s: float = 0.1,
) -> int:
    """Init, spin until SIGINT, SIGTERM or SIGHUP, tear down in order; the exit status.

    rclpy's own signal handler shuts the context down the moment SIGINT arrives, while the
    node's subscriptions still exist and the middleware still delivers to them; the recorder,
    closing its bag in that window, crashed in a middleware thread about one run in ten. Here
    a signal only asks the spin loop to stop (checked every `stop_poll_s` when idle; a
    callback under way finishes), a consumer of batches takes what is already queued for it
    (`_drain`), and the node goes before the context, so a node stopped by any of
    STOP_SIGNALS closes what it holds (the recorder its bag) and exits 0. The handlers
    replace whatever was inherited, also SIG_IGN (a script's background job ignores SIGINT).
    A source whose consumers never appeared (`SourceStartTimeout`) exits 1 with the reason;
    any other exception a callback raises is survived (`_spin_guarded`).
    threads > 1 spins a `JoiningExecutor`, for nodes whose callback groups let a long service
    call run beside their stream callbacks: the callbacks under way when the stop came finish
    (a service call answers) before the node goes, and what they raised is recorded.
    """
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stop_requested = threading.Event()
    handlers = {
        signum: signal.signal(signum, lambda *_: stop_requested.set()) for signum in STOP_SIGNALS
    }
    node = None
    status = 0
    executor = SingleThreadedExecutor() if threads == 1 else JoiningExecutor(num_threads=threads)
    try:
        node = node_factory()
        executor.add_node(node)
        while not stop_requested.is_set() and rclpy.ok():
            _spin_guarded(executor, node, stop_poll_s)
        _drain(executor, node)
    except ExternalShutdownException:
        pass
    except SourceStartTimeout as error:
        node.get_logger().error(f'not started, so no sample is lost: {error}')
        status = 1
    finally:
        for signum, handler in handlers.items():  # a second Ctrl-C interrupts the teardown
            signal.signal(signum, handler)
        executor.shutdown()
        if node is not None:
            for error in getattr(executor, 'late_faults', ()):
                if not _record_fault(node, error):
                    node.get_logger().error(f'a callback raised after the stop: {error!r}')
            node.destroy_node()
        rclpy.try_shutdown()
    return status


class JoiningExecutor(MultiThreadedExecutor):
    """A MultiThreadedExecutor whose shutdown first lets the callbacks it dispatched finish.

    rclpy 7.1's `Executor.shutdown` returns without waiting for outstanding callbacks (its
    wait is skipped once the shut-down flag is set) and destroys the guard condition they
    trigger when done, and its MultiThreadedExecutor leaves its worker threads running
    (ros2/rclpy#1309 fixed that upstream). A callback still running in a worker, or queued
    for one, then failed with 'cannot use Destroyable because destruction was requested',
    printed at exit as an exception 'never retrieved', and a service call under way lost its
    answer. Here shutdown, called once the spin loop has stopped (`run_node`), first joins
    the worker pool (queued callbacks run too), then shuts down as rclpy does; what callbacks
    raised after the last spin is kept in `late_faults`, for the node to record.
    """

    def __init__(self, num_threads: int, **kwargs) -> None:
        super().__init__(num_threads=num_threads, **kwargs)
        self.late_faults: list[BaseException] = []

    def shutdown(self, timeout_sec: float | None = None) -> bool:
        """Wait for every dispatched callback, keep what they raised, then shut down."""
        self._executor.shutdown(wait=True)
        for future in self._futures:
            if future.done() and future.exception() is not None:
                self.late_faults.append(future.exception())
        self._futures.clear()
        return super().shutdown(timeout_sec)


def _spin_guarded(executor, node: Node, timeout_s: float) -> None:
    """One spin; an exception a callback raised is the node's to survive (`CallbackFaults`).

    Logged once, ERROR on /diagnostics, and the node goes on. A source whose
    consumers never came (`SourceStartTimeout`) and an external shutdown still end the loop.
    """
    try:
        executor.spin_once(timeout_sec=timeout_s)
    except (ExternalShutdownException, SourceStartTimeout):
        raise
    except Exception as error:  # the last resort: any fault of a callback
        if not _record_fault(node, error):
            raise


def _record_fault(node: Node, error: BaseException) -> bool:
    """Record a callback's exception on the node's `CallbackFaults`; False if it has none."""
    faults = getattr(node, 'callback_faults', None)
    if faults is None:
        return False
    faults.record('callback', error)
    return True


def _drain(executor, node: Node) -> None:
    """Take what is queued for a consumer of batches (`last_batch_at` set) before it stops."""
    if getattr(node, 'last_batch_at', None) is None:
        return
    deadline = time.monotonic() + DRAIN_MAX_S
    while rclpy.ok() and time.monotonic() < deadline:
        if time.monotonic() - node.last_batch_at > DRAIN_QUIET_S:
            return
        _spin_guarded(executor, node, DRAIN_QUIET_S / 2)


def message_class(msgtype: str) -> type:
    """The generated Python class of a ROS type name such as fmm_interfaces/msg/SampleBatch."""
    package, kind, name = msgtype.split('/')
    return getattr(importlib.import_module(f'{package}.{kind}'), name)
