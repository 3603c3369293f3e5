"""rig_sim: the simulated FMM plant. Applied force in, vibrometer velocity out, batch by batch.

Runs the physics core in streaming form (the oscillator state carries over between batches,
so 500-sample batches give exactly the one-long-call result) and publishes the velocity with
the force batch's sample index and stamp, plus vibrometer noise and the channel's data
acquisition chain (anti-alias filter, zero error and drift, mains hum: `sim.daq`). Its model
terms come from
parameters (`effects`, e.g. `stribeck:mu_static_excess=0.02`), so a test or a demo can hide
an effect in the plant that the analysis is not told about.

The applied force is taken by the stream rules (`fmm_ros.core.signal.stream`), so the
velocity goes out in index order, each sample once: force that never arrived moves the plant
with zero force and leaves a velocity gap; a repeated or stray batch is refused; a restarted
hammer (a new acquisition) restarts the plant at rest, one batch later. As a relay it reports
on the applied force no further than its own velocity consumers have got (ros/flow.py), and
only once they are there, so the hammer's hold-back reaches through it.
"""

import time

import numpy as np
from rclpy.node import Node

from fmm_interfaces.msg import SampleBatch
from fmm_ros.constants import (
    APPLIED_FORCE_TOPIC,
    FORCE,
    SAMPLE_RATE_HZ,
    VELOCITY,
    VELOCITY_TOPIC,
)
from fmm_ros.core.physics.model import OscillatorStream
from fmm_ros.core.physics.rig import PlantRun
from fmm_ros.core.physics.terms import parse_model_term
from fmm_ros.core.signal.stream import AlignedStream
from fmm_ros.errors import UnitError
from fmm_ros.ros import msgs
from fmm_ros.ros.common import (
    RIG_PARAMS,
    chain_from_parameters,
    chain_params,
    rig_from_parameters,
    run_node,
    shared_params,
)
from fmm_ros.ros.flow import SOURCE_PARAMS, FlowGate, ProgressReporter, deliver_last_batches
from fmm_ros.ros.health import ChannelRate, FaultLog, Health, stream_status
from fmm_ros.ros.params import Param, declare_parameters, params_from
from fmm_ros.ros.qos import SAMPLE_QOS
from fmm_ros.ros.sources import SourceCheck
from fmm_ros.sim.daq import ChainStream
from fmm_ros.sim.hammer import add_indexed_noise
from fmm_ros.units import si_factor

PARAMS = (
    Param(
        'input_topic',
        APPLIED_FORCE_TOPIC,
        'Force that drives the plant (SampleBatch) [N]',
        read_only=True,
    ),
    Param(
        'output_topic', VELOCITY_TOPIC, 'Where the vibrometer velocity goes [m/s]', read_only=True
    ),
    *RIG_PARAMS,
    *params_from(PlantRun, ('mu',)),
    Param(
        'effects',
        [''],
        'Extra model terms, each "name" or "name:param=value,..." '
        '(see fmm_ros.core.physics.MODEL_TERMS); [""] for none',
        read_only=True,
    ),
    *params_from(PlantRun, ('integrator',)),
    Param(
        'noise_std_m_s',
        1e-4,
        'Vibrometer noise, standard deviation [m/s] (it passes the anti-alias filter)',
        limits=(0.0, 1.0),
        read_only=True,
    ),
    *chain_params('velocity', 'm/s', 'm_s', 1.0),
    Param(
        'full_scale_m_s',
        0.5,
        'Vibrometer range [m/s] (OFV-5000 at 50 mm/s/V, +-10 V)',
        limits=(1e-6, 100.0),
        read_only=True,
    ),
    *shared_params('seed', 'frame_id', seed=1, frame_id='vibrometer'),
    Param(
        'velocity_unit',
        'm/s',
        'Unit the velocity is published in, as a vibrometer may be set (any velocity unit of '
        'fmm_ros.units)',
        read_only=True,
    ),
    *(param for param in SOURCE_PARAMS if param.name != 'flow_window_s'),
)


# Longest stretch of missing force the plant is stepped through [s of signal].
UNFORCED_LIMIT_S = 60.0


class RigSim(Node):
    """Steps the plant with each applied-force batch and publishes the measured velocity."""

    def __init__(self, **kwargs) -> None:
        super().__init__('rig_sim', **kwargs)
        self.config = declare_parameters(self, PARAMS)
        cfg = self.config
        self.rig = rig_from_parameters(cfg)
        self.effects = tuple(parse_model_term(text) for text in cfg['effects'] if text.strip())
        self._plant: OscillatorStream | None = None
        # The plant's kernels compile (or load from numba's cache) here, before any consumer
        # hears of the node. Compiled on the first batch instead, on a fresh install with both
        # cores busy, the plant fell silent for 20 s mid-stream: the hammer stopped waiting
        # for it and the analyzer and fitter declared the late velocity missing.
        self._new_plant(SAMPLE_RATE_HZ).step(np.zeros(2))
        self.next_index = 0
        self._velocity = np.empty(0)
        self._chain = chain_from_parameters(cfg, 'm_s')
        self._chain_stream: ChainStream | None = None
        self._runs: list[tuple[int, np.ndarray]] = []  # velocity taken in this callback
        self._per_unit = 1.0 / si_factor(VELOCITY.quantity, cfg['velocity_unit'])
        self._publisher = self.create_publisher(SampleBatch, cfg['output_topic'], SAMPLE_QOS)
        self.stream = AlignedStream(self, quantities=(FORCE.quantity,))
        self.gate = FlowGate(
            self,
            [self._publisher],
            wait_for=cfg['wait_for_consumers'],
            start_timeout_s=cfg['start_timeout_s'],
            on_progress=self._report,
            silent_after_s=cfg['silent_after_s'],
        )
        subscription = self.create_subscription(
            SampleBatch, cfg['input_topic'], self._on_force, SAMPLE_QOS
        )
        self._input = subscription.topic_name
        self._output = self._publisher.topic_name
        # Reports on the applied force only once its own consumers are there.
        self.reporter = ProgressReporter(self, [self._input], announce=False)
        self._waiting = self.create_timer(0.1, self._await_consumers)
        self.last_batch_at = 0.0  # a consumer of batches: drained before it stops
        self._rates: dict[str, ChannelRate] = {}
        self._faults = FaultLog(self)
        health = Health(self)
        health.add('stream', lambda: stream_status(self.stream.ledger, self._rates))
        health.add('sources', SourceCheck(self, {FORCE.quantity: self._input}).status)
        terms = ', '.join(str(effect) for effect in self.effects) or 'none'
        self.get_logger().info(
            f'plant m={self.rig.mass_kg} kg k={self.rig.stiffness_n_per_m} N/m '
            f'c={self.rig.damping_n_s_per_m} N*s/m N={self.rig.normal_force_n:.3f} N '
            f'mu={cfg["mu"]}, extra terms: {terms}; driven by {self._input}'
        )

    def _await_consumers(self) -> None:
        if self.gate.ready():
            self.destroy_timer(self._waiting)
            self.reporter.announce()

    def _report(self) -> None:
        """Report on the applied force up to where the velocity consumers have got."""
        if self.stream.started:
            taken = self.stream.next_index(FORCE.quantity)
            self.reporter.update(
                self._input,
                min(taken, self.gate.slowest_index(self._output)),
                self.stream.sample_rate_hz,
            )

    def _on_force(self, msg: SampleBatch) -> None:
        self.last_batch_at = time.monotonic()
        detail = f'last at {msg.first_sample_index}'
        try:
            batch = msgs.si_stream_batch(msg, FORCE.quantity)
        except UnitError as error:  # refused by name, never read as if it were N
            self.stream.refuse_malformed(FORCE.quantity, len(msg.samples), kind='unit')
            detail = str(error)
        else:
            try:
                self.stream.feed(FORCE.quantity, batch)
            except ValueError:
                self.stream.refuse_malformed(FORCE.quantity, len(batch.samples))
            self._rates.setdefault(FORCE.quantity, ChannelRate()).newest_stamp_ns = batch.stamp_ns
        for first, velocity in self._runs:  # in index order, each sample once
            stamp = msgs.stamp_ns(msg.header.stamp) + round(
                (first - msg.first_sample_index) / msg.sample_rate_hz * 1e9
            )
            out = msgs.sample_batch(
                velocity * self._per_unit if self._per_unit != 1.0 else velocity,
                quantity=VELOCITY,
                sample_rate_hz=msg.sample_rate_hz,
                first_sample_index=first,
                stamp=msgs.time_msg(stamp),
                frame_id=self.config['frame_id'],
                full_scale=self.config['full_scale_m_s'] * self._per_unit,
            )
            out.unit = self.config['velocity_unit']
            self._publisher.publish(out)
            self.gate.sent(first + velocity.size)
        self._runs = []
        self._report()
        self._faults.check(self.stream.ledger, detail)

    def destroy_node(self) -> None:
        """Deliver the last velocity, log the final ledger of its input."""
        deliver_last_batches([self._publisher])
        for ledger in self.stream.ledger.values():
            self.get_logger().info(f'stopped: {ledger.summary()}')
        super().destroy_node()

    # -- the stream's sink: the plant -----------------------------------------------------------

    def begin(self, sample_rate_hz: float, first_index: int) -> None:
        """An acquisition begins: the plant starts at rest at its first index."""
        self._plant = self._new_plant(sample_rate_hz)
        self.next_index = first_index
        self._chain_stream = ChainStream(self._chain, sample_rate_hz, seed=self.config['seed'])
        self.gate.begin(first_index)

    def _new_plant(self, sample_rate_hz: float) -> OscillatorStream:
        """The configured plant at rest."""
        return OscillatorStream(
            sample_rate_hz,
            rig=self.rig,
            mu=self.config['mu'],
            effects=self.effects,
            integrator=self.config['integrator'],
        )

    def end(self, reason: str) -> None:
        """The acquisition the plant follows has ended (a new one began)."""
        self.get_logger().warning(f'applied force restarted ({reason}): the plant starts again')

    def take(self, quantity: str, first_index: int, samples: np.ndarray, full_scale: float) -> None:
        """Force at the watermark: step the plant, keep the velocity for this callback's message."""
        velocity = self._step(samples).copy()
        if self._runs and self._runs[-1][0] + self._runs[-1][1].size == first_index:
            first, earlier = self._runs[-1]
            self._runs[-1] = (first, np.concatenate((earlier, velocity)))
        else:
            self._runs.append((first_index, velocity))

    def missing(self, quantity: str, start: int, stop: int) -> None:
        """Force that never arrived: the plant runs through it unforced; no velocity for it.

        Friction stops the free plant within seconds, so a long gap is stepped only through
        its first UNFORCED_LIMIT_S (the plant is at rest after it, whatever the gap's length).
        """
        limit = int(UNFORCED_LIMIT_S * self.stream.sample_rate_hz)
        self._step(np.zeros(min(stop - start, limit)))
        self.next_index = stop
        # The sensor chain goes on after the gap, however long (a stall of any length: a gap
        # past the limit once left the chain behind, and every later batch was refused).
        self._chain_stream.skip(stop)

    def _step(self, force_n: np.ndarray) -> np.ndarray:
        """Advance the plant over force_n and return the noisy vibrometer output (reused buffer)."""
        if self._velocity.size != force_n.size:
            self._velocity = np.empty(force_n.size)
        _, velocity = self._plant.step(force_n)
        np.copyto(self._velocity, velocity)
        add_indexed_noise(
            self._velocity, self.next_index, self.config['noise_std_m_s'], self.config['seed']
        )
        self._chain_stream.apply(self.next_index, self._velocity)
        self.next_index += force_n.size
        return self._velocity


def main(args: list[str] | None = None) -> int:
    """`ros2 run fmm_ros rig_sim`."""
    return run_node(RigSim, args)


if __name__ == '__main__':
    main()
