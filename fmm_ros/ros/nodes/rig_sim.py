"""rig_sim: the simulated FMM plant. Applied force in, vibrometer velocity out, batch by batch.

Runs the physics core in streaming form (the oscillator state carries over between batches,
so 500-sample batches give exactly the one-long-call result) and publishes the velocity with
the force batch's sample index and stamp, plus vibrometer noise and the channel's data
acquisition chain (anti-alias filter, zero error and drift, mains hum: `sim.daq`). Its model
terms come from
parameters (`effects`, e.g. `stribeck:mu_static_excess=0.02`), so a test or a demo can hide
an effect in the plant that the analysis is not told about.
"""

import numpy as np
from rclpy.node import Node

from fmm_interfaces.msg import SampleBatch
from fmm_ros.constants import APPLIED_FORCE_TOPIC, PAPER_MU, VELOCITY, VELOCITY_TOPIC
from fmm_ros.core.physics.model import INTEGRATORS, OscillatorStream
from fmm_ros.core.physics.terms import parse_model_term
from fmm_ros.ros import msgs
from fmm_ros.ros.common import (
    RIG_PARAMS,
    SAMPLE_QOS,
    chain_from_parameters,
    chain_params,
    rig_from_parameters,
    run_node,
)
from fmm_ros.ros.params import Param, declare_parameters
from fmm_ros.sim.daq import ChainStream
from fmm_ros.sim.hammer import add_indexed_noise

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
    Param(
        'mu',
        PAPER_MU,
        'Coulomb friction coefficient of the plant [-]',
        limits=(0.0, 2.0),
        read_only=True,
    ),
    Param(
        'effects',
        [''],
        'Extra model terms, each "name" or "name:param=value,..." '
        '(see fmm_ros.core.physics.MODEL_TERMS); [""] for none',
        read_only=True,
    ),
    Param('integrator', 'exact', 'Physics integrator', choices=INTEGRATORS, read_only=True),
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
    Param('seed', 1, 'Seed of the vibrometer noise [-]', limits=(0, 2**31 - 1), read_only=True),
    Param('frame_id', 'vibrometer', 'Sensor name in the message header', read_only=True),
)


class RigSim(Node):
    """Steps the plant with each applied-force batch and publishes the measured velocity."""

    def __init__(self, **kwargs) -> None:
        super().__init__('rig_sim', **kwargs)
        self.config = declare_parameters(self, PARAMS)
        cfg = self.config
        self.rig = rig_from_parameters(cfg)
        self.effects = tuple(parse_model_term(text) for text in cfg['effects'] if text.strip())
        self._stream: OscillatorStream | None = None
        self._sample_rate_hz = 0.0
        self.next_index = 0
        self._velocity = np.empty(0)
        self._chain = chain_from_parameters(cfg, 'm_s')
        self._chain_stream: ChainStream | None = None
        self._publisher = self.create_publisher(SampleBatch, cfg['output_topic'], SAMPLE_QOS)
        self.create_subscription(SampleBatch, cfg['input_topic'], self._on_force, SAMPLE_QOS)
        terms = ', '.join(str(effect) for effect in self.effects) or 'none'
        self.get_logger().info(
            f'plant m={self.rig.mass_kg} kg k={self.rig.stiffness_n_per_m} N/m '
            f'c={self.rig.damping_n_s_per_m} N*s/m N={self.rig.normal_force_n:.3f} N '
            f'mu={cfg["mu"]}, extra terms: {terms}; driven by {cfg["input_topic"]}'
        )

    def _on_force(self, msg: SampleBatch) -> None:
        force = msgs.batch_samples(msg)
        if self._stream is None:
            self._start(msg)
        elif msg.sample_rate_hz != self._sample_rate_hz:
            self.get_logger().error(
                f'force batch at {msg.sample_rate_hz} Hz but the plant runs at '
                f'{self._sample_rate_hz} Hz: batch {msg.first_sample_index} ignored'
            )
            return
        if msg.first_sample_index < self.next_index:
            self.get_logger().warning(
                f'force batch {msg.first_sample_index} repeats samples already simulated '
                f'(next is {self.next_index}): ignored'
            )
            return
        if msg.first_sample_index > self.next_index:
            missing = msg.first_sample_index - self.next_index
            self.get_logger().warning(
                f'{missing} force samples never arrived before {msg.first_sample_index}: the '
                'plant is run through them with zero applied force'
            )
            self._step(np.zeros(missing))
        velocity = self._step(force)
        out = msgs.sample_batch(
            velocity,
            quantity=VELOCITY,
            sample_rate_hz=self._sample_rate_hz,
            first_sample_index=msg.first_sample_index,
            stamp=msg.header.stamp,
            frame_id=self.config['frame_id'],
            full_scale=self.config['full_scale_m_s'],
        )
        self._publisher.publish(out)

    def _start(self, msg: SampleBatch) -> None:
        """The plant starts at rest at the first batch's sample index."""
        self._sample_rate_hz = msg.sample_rate_hz
        self._stream = OscillatorStream(
            msg.sample_rate_hz,
            rig=self.rig,
            mu=self.config['mu'],
            effects=self.effects,
            integrator=self.config['integrator'],
        )
        self.next_index = msg.first_sample_index
        self._chain_stream = ChainStream(self._chain, msg.sample_rate_hz, seed=self.config['seed'])

    def _step(self, force_n: np.ndarray) -> np.ndarray:
        """Advance the plant over force_n and return the noisy vibrometer output (reused buffer)."""
        if self._velocity.size != force_n.size:
            self._velocity = np.empty(force_n.size)
        _, velocity = self._stream.step(force_n)
        np.copyto(self._velocity, velocity)
        add_indexed_noise(
            self._velocity, self.next_index, self.config['noise_std_m_s'], self.config['seed']
        )
        self._chain_stream.apply(self.next_index, self._velocity)
        self.next_index += force_n.size
        return self._velocity


def main(args: list[str] | None = None) -> None:
    """`ros2 run fmm_ros rig_sim`."""
    run_node(RigSim, args)


if __name__ == '__main__':
    main()
