"""hammer_sim: a simulated impact hammer running the paper's session, published in batches.

Publishes what the force channel reports on /fmm/force and, for the simulated plant only, the
force the hammer actually applies on /fmm/sim/applied_force (same sample indices): rig_sim is
driven by the applied force, as the real rig is, so sensor noise never moves the plant. The
channel's data acquisition chain (anti-alias filter, zero error and drift, mains hum:
`sim.daq`) acts on the reported force only.
Paced to the wall clock; `rate_factor` runs it faster (it can be changed live). It holds
its first sample until the consumers in `wait_for_consumers` have reported, and never runs
more than the flow window ahead of the slowest (ros/flow.py): above what the machine
sustains it runs slower than asked rather than have a batch dropped.
"""

import numpy as np
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.parameter import Parameter

from fmm_interfaces.msg import SampleBatch
from fmm_ros.constants import (
    APPLIED_FORCE_TOPIC,
    FORCE,
    FORCE_TOPIC,
)
from fmm_ros.errors import BadInputError
from fmm_ros.ros import msgs
from fmm_ros.ros.common import chain_from_parameters, chain_params, run_node, shared_params
from fmm_ros.ros.flow import MAX_BATCHES_PARAM, SOURCE_PARAMS, PacedSource
from fmm_ros.ros.health import Health
from fmm_ros.ros.params import Param, declare_parameters
from fmm_ros.ros.qos import SAMPLE_QOS
from fmm_ros.ros.timebase import CLOCK_PARAM, ClockPublisher
from fmm_ros.sim.daq import ChainStream
from fmm_ros.sim.hammer import HammerStream, session_schedule
from fmm_ros.units import si_factor

PARAMS = (
    *shared_params('sample_rate_hz', 'batch_size'),
    *shared_params('rate_factor', read_only=False),
    *shared_params('level_names', 'level_peak_forces_n', 'hits_per_level'),
    Param(
        'hit_spacing_s',
        40.0,
        'Time from one hit to the next [s] (record window + settling)',
        limits=(0.5, 86_400.0),
        read_only=True,
    ),
    Param(
        'first_hit_s',
        2.0,
        'Time of the first hit after start [s]',
        limits=(0.0, 86_400.0),
        read_only=True,
    ),
    Param(
        'peak_spread_std_n',
        20.0,
        'Hand scatter of the peak force around nominal [N]',
        limits=(0.0, 1000.0),
        read_only=True,
    ),
    Param(
        'contact_scale',
        1.0,
        "Contact duration against the paper's tip [-] (below 1: a harder tip, sharper hits)",
        limits=(0.05, 10.0),
        read_only=True,
    ),
    Param(
        'noise_std_n',
        0.2,
        'Force sensor noise, standard deviation [N] (it passes the anti-alias filter)',
        limits=(0.0, 100.0),
        read_only=True,
    ),
    *chain_params('force', 'N', 'n', 1000.0),
    Param(
        'full_scale_n',
        22_240.0,
        'Force sensor range [N] (PCB 086D05: 22.24 kN)',
        limits=(1.0, 1e6),
        read_only=True,
    ),
    *shared_params('seed', 'frame_id', frame_id='hammer'),
    Param(
        'force_unit',
        'N',
        'Unit the measured force is published in, as a lab DAQ may be set (any force unit '
        'of fmm_ros.units; the applied force to rig_sim stays in N)',
        read_only=True,
    ),
    *SOURCE_PARAMS,
    MAX_BATCHES_PARAM,
    CLOCK_PARAM,
)


class HammerSim(Node):
    """Publishes the simulated session's force, one batch per tick of the sample clock."""

    def __init__(self, **kwargs) -> None:
        super().__init__('hammer_sim', **kwargs)
        self.config = declare_parameters(self, PARAMS)
        names, peaks = self.config['level_names'], self.config['level_peak_forces_n']
        if len(names) != len(peaks):
            raise BadInputError(
                f'level_names has {len(names)} entries but level_peak_forces_n '
                f'has {len(peaks)}: give one peak force per level'
            )
        rate = self.config['sample_rate_hz']
        self.schedule = session_schedule(
            list(zip(names, peaks, strict=True)),
            self.config['hits_per_level'],
            sample_rate_hz=rate,
            spacing_s=self.config['hit_spacing_s'],
            first_hit_s=self.config['first_hit_s'],
            rng=self.config['seed'],
            spread_std_n=self.config['peak_spread_std_n'],
            contact_scale=self.config['contact_scale'],
        )
        self.stream = HammerStream(
            self.schedule, rate, noise_std_n=self.config['noise_std_n'], seed=self.config['seed']
        )
        self.chain = ChainStream(
            chain_from_parameters(self.config, 'n'), rate, seed=self.config['seed']
        )
        self.next_index = 0
        self._per_unit = 1.0 / si_factor(FORCE.quantity, self.config['force_unit'])
        self._measured_pub = self.create_publisher(SampleBatch, FORCE_TOPIC, SAMPLE_QOS)
        self._applied_pub = self.create_publisher(SampleBatch, APPLIED_FORCE_TOPIC, SAMPLE_QOS)
        batch = self._batch = self.config['batch_size']  # at x1; _pace sizes it to the pace
        self._applied = np.empty(batch)
        self._measured = np.empty(batch)
        self._start_stamp = self.get_clock().now()
        self.clock = ClockPublisher(self, self.config['publish_clock'])
        self._timer = None
        self._held = False
        self.source = PacedSource(
            self,
            [self._measured_pub, self._applied_pub],
            self.config,
            batches_per_s=1.0,
            window_samples=PacedSource.window_samples(self.config, rate, batch),
            pace_label=f'x{self.config["rate_factor"]:g} real time',
            release=self._on_tick,
            sample_rate_hz=rate,
        )
        self._pace(self.config['rate_factor'])
        self.add_post_set_parameters_callback(self._on_parameters)
        Health(self).add(
            'source',
            lambda: self.source.status(rate, self.config['rate_factor']),
        )
        self.get_logger().info(
            f'{len(self.schedule)} hits at {", ".join(names)} ({peaks} N), '
            f'{self.config["hit_spacing_s"]} s apart, {rate:g} Hz in batches of {self._batch}, '
            f'x{self.config["rate_factor"]:g} real time'
        )

    @property
    def hits_sent(self) -> int:
        """Hits whose first force sample has been published."""
        return self.stream.hits_started_before(self.next_index)

    @property
    def schedule_done(self) -> bool:
        """True once every hit's pulse has been published."""
        return self.next_index >= self.stream.end_index

    def _pace(self, rate_factor: float) -> None:
        """(Re)start the timer at one batch of sample time per tick, paced from now.

        Above max_batches_per_s a batch holds a whole multiple of batch_size samples
        (`PacedSource.paced_batch`), so the messages a second, and their cost, stay bounded.
        """
        sample_rate = self.config['sample_rate_hz']
        rate = sample_rate * rate_factor
        self.config['rate_factor'] = rate_factor
        self.source.label = f'x{rate_factor:g} real time'
        self._batch = PacedSource.paced_batch(
            self.config, sample_rate, self.config['batch_size'], rate_factor
        )
        if self._applied.size != self._batch:
            self._applied, self._measured = np.empty(self._batch), np.empty(self._batch)
        self.source.window = PacedSource.window_samples(self.config, sample_rate, self._batch)
        self.source.pacer.restart(rate / self._batch, self.source.pacer.released)
        if self._timer is not None:
            self.destroy_timer(self._timer)
        self._timer = self.create_timer(self._batch / rate, self._on_tick)

    def _on_parameters(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == 'rate_factor':
                self._pace(parameter.value)

    def hold(self) -> None:
        """Publish nothing more (a session driven from outside is over)."""
        self._held = True

    def _on_tick(self) -> None:
        if self._held or not self.source.ready():
            return
        for _ in range(self.source.due(self._batch)):
            self._publish_batch()

    def _publish_batch(self) -> None:
        first = self.next_index
        rate = self.config['sample_rate_hz']
        stamp = (self._start_stamp + Duration(nanoseconds=round(first / rate * 1e9))).to_msg()
        self.stream.applied(first, self._applied)
        self.stream.measured(self._applied, first, self._measured)
        self.chain.apply(first, self._measured)
        common = dict(
            quantity=FORCE,
            sample_rate_hz=rate,
            first_sample_index=first,
            stamp=stamp,
            frame_id=self.config['frame_id'],
            full_scale=self.config['full_scale_n'],
        )
        self._applied_pub.publish(msgs.sample_batch(self._applied, **common))
        if self._per_unit != 1.0:  # as a DAQ set to another unit publishes it
            self._measured *= self._per_unit
            common['full_scale'] *= self._per_unit
        measured = msgs.sample_batch(self._measured, **common)
        measured.unit = self.config['force_unit']
        self._measured_pub.publish(measured)
        self.next_index = first + self._applied.size
        self.source.sent(self.next_index)
        done = self.next_index >= self.stream.end_index > first
        self.clock.advance(
            self._start_stamp.nanoseconds + round(self.next_index / rate * 1e9), force=done
        )
        if done:
            self.get_logger().info(f'session complete: {len(self.schedule)} hits sent')

    def destroy_node(self) -> None:
        """Deliver the last batches, say what went out (a recording is checked against it)."""
        self.source.finish()
        self.get_logger().info(
            f'stopped: samples 0..{self.next_index} published on {self._measured_pub.topic_name} '
            f'({self.hits_sent} of {len(self.schedule)} hits)'
        )
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """`ros2 run fmm_ros hammer_sim`."""
    return run_node(HammerSim, args)


if __name__ == '__main__':
    main()
