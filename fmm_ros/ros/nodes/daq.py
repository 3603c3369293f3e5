"""daq: the real rig's acquisition, publishing force and velocity with one shared sample index.

Backends:

- `nidaqmx`: an NI-DAQmx device, hardware-clocked continuous acquisition of an IEPE force
  channel (impact hammer: sensitivity in mV/N, excitation current) and the response: a
  voltage channel (laser vibrometer decoder output, scaled in m/s per V), or with
  `response_sensor:=iepe_accelerometer` an IEPE accelerometer channel (sensitivity in mV/g,
  published in m/s^2 as quantity 'acceleration' on the response topic); an every-N-samples
  callback reads
  each batch of both channels into one preallocated buffer and publishes it. Needs the
  optional `nidaqmx` package and NI's driver; without them the node stops at start-up and
  says what to install.
- `file`: streams a recorded lab file (CSV, NPZ, MATLAB, TDMS, read by the bag importers
  with an explicit channel mapping) at its own sample rate x `rate_factor`, for dry runs
  of the analysis chain without the rig; its response (velocity, acceleration or
  displacement) goes out as the quantity it is.

Either holds its first sample until the consumers in `wait_for_consumers` have reported
(ros/flow.py). The file backend also never runs more than the flow window ahead of the
slowest consumer (it slows down instead); the hardware clock of a DAQ cannot slow down, so
there the device buffer (`buffer_s`) absorbs what the consumers lag.
"""

from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import numpy as np
from rclpy.duration import Duration
from rclpy.node import Node

from fmm_interfaces.msg import SampleBatch
from fmm_ros.constants import (
    ACCELERATION,
    DISPLACEMENT,
    FORCE,
    FORCE_TOPIC,
    RESPONSE_CHANNELS,
    VELOCITY,
    VELOCITY_TOPIC,
)
from fmm_ros.errors import BadInputError
from fmm_ros.io.labfiles import ImportMapping, load_mapping, read_lab_file
from fmm_ros.ros import msgs
from fmm_ros.ros.common import run_node, shared_params
from fmm_ros.ros.flow import MAX_BATCHES_PARAM, SOURCE_PARAMS, PacedSource, deliver_last_batches
from fmm_ros.ros.health import Health
from fmm_ros.ros.params import Param, declare_parameters
from fmm_ros.ros.qos import SAMPLE_QOS
from fmm_ros.ros.timebase import CLOCK_PARAM, ClockPublisher

INSTALL_HINT = (
    'the nidaqmx backend needs NI-DAQmx: `pip install nidaqmx` into the environment '
    "that runs this node, then NI's driver (`python -m nidaqmx installdriver`, or "
    'the NI Linux Device Drivers package); use backend:=file for a dry run'
)

RESPONSE_SENSORS = ('vibrometer', 'iepe_accelerometer')
RESPONSE_FRAMES = {
    VELOCITY.quantity: 'vibrometer',
    ACCELERATION.quantity: 'accelerometer',
    DISPLACEMENT.quantity: 'displacement_sensor',
}
"""The frame_id of each response sensor's batches."""

PARAMS = (
    Param('backend', 'nidaqmx', 'Acquisition backend', choices=('nidaqmx', 'file'), read_only=True),
    *shared_params('sample_rate_hz', 'batch_size'),
    Param('force_channel', 'Dev1/ai0', 'Physical channel of the hammer (IEPE)', read_only=True),
    Param(
        'hammer_sensitivity_mv_per_n',
        0.2248,
        'Hammer sensitivity [mV/N] (PCB 086D05: 1 mV/lbf)',
        limits=(1e-4, 1e4),
        read_only=True,
    ),
    Param(
        'iepe_current_a', 0.004, 'IEPE excitation current [A]', limits=(0.0, 0.02), read_only=True
    ),
    Param(
        'force_range_n',
        5000.0,
        'Force channel range +- [N] (also the clipping level)',
        limits=(1.0, 1e6),
        read_only=True,
    ),
    Param(
        'velocity_channel', 'Dev1/ai1', 'Physical channel of the vibrometer output', read_only=True
    ),
    Param(
        'velocity_scale_m_s_per_v',
        0.05,
        'Vibrometer decoder scale [m/s per V]',
        limits=(1e-9, 1e3),
        read_only=True,
    ),
    Param(
        'velocity_range_v',
        10.0,
        'Velocity channel range +- [V]',
        limits=(0.01, 100.0),
        read_only=True,
    ),
    Param(
        'response_sensor',
        'vibrometer',
        'What measures the response (nidaqmx): the vibrometer voltage or an IEPE accelerometer',
        choices=RESPONSE_SENSORS,
        read_only=True,
    ),
    Param(
        'accelerometer_channel',
        'Dev1/ai1',
        'Physical channel of the IEPE accelerometer',
        read_only=True,
    ),
    Param(
        'accelerometer_sensitivity_mv_per_g',
        100.0,
        'Accelerometer sensitivity [mV/g] (from its calibration sheet)',
        limits=(1e-3, 1e5),
        read_only=True,
    ),
    Param(
        'acceleration_range_m_s2',
        500.0,
        'Acceleration channel range +- [m/s^2] (also the saturation level)',
        limits=(1e-3, 1e6),
        read_only=True,
    ),
    Param('buffer_s', 10.0, 'Device buffer length [s]', limits=(0.1, 3600.0), read_only=True),
    Param('file_path', '', 'Lab file to stream (file backend)', read_only=True),
    Param(
        'file_mapping',
        '',
        'YAML channel mapping of the file (see fmm import); "" for what the file states '
        '(time_s, force_n and velocity_m_s, acceleration_m_s2 or displacement_m)',
        read_only=True,
    ),
    *shared_params('rate_factor'),
    Param(
        'loop',
        False,
        'File backend: start over at the end (the sample index runs on)',
        read_only=True,
    ),
    *SOURCE_PARAMS,
    MAX_BATCHES_PARAM,
    CLOCK_PARAM,
)

Publish = Callable[[int, np.ndarray, np.ndarray], None]


class Daq(Node):
    """Publishes both channels of one acquisition as SampleBatch pairs with a shared index."""

    def __init__(self, **kwargs) -> None:
        super().__init__('daq', **kwargs)
        self.config = declare_parameters(self, PARAMS)
        self._force_pub = self.create_publisher(SampleBatch, FORCE_TOPIC, SAMPLE_QOS)
        self._velocity_pub = self.create_publisher(SampleBatch, VELOCITY_TOPIC, SAMPLE_QOS)
        self._start_stamp = self.get_clock().now()
        self.clock = ClockPublisher(self, self.config['publish_clock'])
        self.batches_published = 0
        self.health = Health(self)
        backend = {'nidaqmx': NidaqmxBackend, 'file': FileBackend}[self.config['backend']]
        self.backend = backend(self, self._publish)
        self.get_logger().info(f'{self.config["backend"]} backend: {self.backend.describe()}')

    @property
    def publishers_of_samples(self) -> list:
        """The force and velocity publishers (what a backend's flow control gates)."""
        return [self._force_pub, self._velocity_pub]

    def _publish(
        self, first_sample_index: int, force_n: np.ndarray, velocity_m_s: np.ndarray
    ) -> None:
        """Publish one batch of both channels (called from the backend's thread or timer)."""
        rate = self.backend.sample_rate_hz
        stamp = (
            self._start_stamp + Duration(nanoseconds=round(first_sample_index / rate * 1e9))
        ).to_msg()
        for publisher, samples, quantity, frame, full_scale in (
            (self._force_pub, force_n, FORCE, 'hammer', self.backend.force_full_scale),
            (
                self._velocity_pub,
                velocity_m_s,
                self.backend.response,
                RESPONSE_FRAMES[self.backend.response.quantity],
                self.backend.velocity_full_scale,
            ),
        ):
            publisher.publish(
                msgs.sample_batch(
                    samples,
                    quantity=quantity,
                    sample_rate_hz=rate,
                    first_sample_index=first_sample_index,
                    stamp=stamp,
                    frame_id=frame,
                    full_scale=full_scale,
                )
            )
        self.batches_published += 1
        end = first_sample_index + len(force_n)
        self.clock.advance(self._start_stamp.nanoseconds + round(end / rate * 1e9))

    def destroy_node(self) -> None:
        """Stop the acquisition, deliver its last batches, say what went out."""
        self.backend.close()
        deliver_last_batches(self.publishers_of_samples)
        self.get_logger().info(
            f'stopped: samples 0..{self.backend.next_index} published on '
            f'{self._force_pub.topic_name} and {self._velocity_pub.topic_name}'
        )
        super().destroy_node()


class NidaqmxBackend:
    """Continuous hardware-clocked acquisition on an NI-DAQmx device."""

    def __init__(self, node: Daq, publish: Publish) -> None:
        try:
            import nidaqmx
            from nidaqmx import constants
            from nidaqmx.stream_readers import AnalogMultiChannelReader
        except ImportError as error:
            raise RuntimeError(f'nidaqmx is not installed: {INSTALL_HINT}') from error
        cfg = node.config
        self.sample_rate_hz = cfg['sample_rate_hz']
        self.force_full_scale = cfg['force_range_n']
        accelerometer = cfg['response_sensor'] == 'iepe_accelerometer'
        self.response = ACCELERATION if accelerometer else VELOCITY
        if accelerometer:
            self.velocity_full_scale = cfg['acceleration_range_m_s2']
            response = (
                f'{cfg["accelerometer_channel"]} (IEPE accelerometer '
                f'{cfg["accelerometer_sensitivity_mv_per_g"]} mV/g)'
            )
        else:
            self.velocity_full_scale = cfg['velocity_range_v'] * cfg['velocity_scale_m_s_per_v']
            response = f'{cfg["velocity_channel"]} ({cfg["velocity_scale_m_s_per_v"]} m/s/V)'
        self._describe = (
            f'{cfg["force_channel"]} (IEPE {cfg["hammer_sensitivity_mv_per_n"]} '
            f'mV/N, {cfg["iepe_current_a"] * 1e3:g} mA), {response}, '
            f'{self.sample_rate_hz:g} Hz'
        )
        try:
            self.task = nidaqmx.Task()
        except nidaqmx.errors.DaqNotFoundError as error:
            raise RuntimeError(f'NI-DAQmx driver not found ({error}); {INSTALL_HINT}') from error
        try:
            self._add_channels(cfg, constants, accelerometer)
            self.task.timing.cfg_samp_clk_timing(
                self.sample_rate_hz,
                sample_mode=constants.AcquisitionType.CONTINUOUS,
                samps_per_chan=int(cfg['buffer_s'] * self.sample_rate_hz),
            )
            batch = cfg['batch_size']
            reader = AnalogMultiChannelReader(self.task.in_stream)
            buffer = np.empty((2, batch))
            scale = 1.0 if accelerometer else cfg['velocity_scale_m_s_per_v']
            self.next_index = 0

            def on_samples(task_handle, event_type, number_of_samples, callback_data) -> int:
                reader.read_many_sample(buffer, number_of_samples_per_channel=batch, timeout=0.0)
                publish(self.next_index, buffer[0], buffer[1] * scale)
                self.next_index += batch
                self._source.sent(self.next_index)
                return 0

            self.task.register_every_n_samples_acquired_into_buffer_event(batch, on_samples)
        except nidaqmx.errors.DaqError as error:
            self.task.close()
            raise RuntimeError(f'NI-DAQmx refused the acquisition: {error}') from error
        # The hardware clock cannot wait: the task starts once the consumers are there.
        self._source = PacedSource(
            node,
            node.publishers_of_samples,
            cfg,
            batches_per_s=self.sample_rate_hz / batch,
            window_samples=PacedSource.window_samples(cfg, self.sample_rate_hz, batch),
            pace_label='the hardware clock',
            sample_rate_hz=self.sample_rate_hz,
        )
        node.health.add('source', lambda: self._source.status(self.sample_rate_hz, 1.0))
        self._daq_error = nidaqmx.errors.DaqError
        self._starting = node.create_timer(0.1, self._start_when_ready)
        self._node = node

    def _add_channels(self, cfg: dict, constants: ModuleType, accelerometer: bool) -> None:
        """The hammer's IEPE force channel, then the response channel.

        The response is an IEPE accelerometer or the vibrometer's voltage; constants is
        nidaqmx's module, imported by `__init__` only (the package runs without nidaqmx).
        """
        self.task.ai_channels.add_ai_force_iepe_chan(
            cfg['force_channel'],
            min_val=-cfg['force_range_n'],
            max_val=cfg['force_range_n'],
            units=constants.ForceUnits.NEWTONS,
            sensitivity=cfg['hammer_sensitivity_mv_per_n'],
            sensitivity_units=constants.ForceIEPESensorSensitivityUnits.MILLIVOLTS_PER_NEWTON,
            current_excit_source=constants.ExcitationSource.INTERNAL,
            current_excit_val=cfg['iepe_current_a'],
        )
        if accelerometer:
            sensitivity_units = constants.AccelSensitivityUnits
            self.task.ai_channels.add_ai_accel_chan(
                cfg['accelerometer_channel'],
                min_val=-cfg['acceleration_range_m_s2'],
                max_val=cfg['acceleration_range_m_s2'],
                units=constants.AccelUnits.METERS_PER_SECOND_SQUARED,
                sensitivity=cfg['accelerometer_sensitivity_mv_per_g'],
                # nidaqmx >= 0.8 spells it MILLIVOLTS_PER_G, older releases M_VOLTS_PER_G.
                sensitivity_units=getattr(sensitivity_units, 'MILLIVOLTS_PER_G', None)
                or sensitivity_units.M_VOLTS_PER_G,
                current_excit_source=constants.ExcitationSource.INTERNAL,
                current_excit_val=cfg['iepe_current_a'],
            )
        else:
            self.task.ai_channels.add_ai_voltage_chan(
                cfg['velocity_channel'],
                min_val=-cfg['velocity_range_v'],
                max_val=cfg['velocity_range_v'],
            )

    def _start_when_ready(self) -> None:
        if not self._source.ready():
            return
        self._node.destroy_timer(self._starting)
        try:
            self.task.start()
        except self._daq_error as error:
            raise RuntimeError(f'NI-DAQmx refused to start: {error}') from error

    def describe(self) -> str:
        """One line for the start-up log."""
        return self._describe

    def close(self) -> None:
        """Stop and release the task."""
        self.task.close()


class FileBackend:
    """Streams a recorded lab file at its sample rate x rate_factor, as a dry-run rig."""

    def __init__(self, node: Daq, publish: Publish) -> None:
        cfg = node.config
        if not cfg['file_path']:
            raise BadInputError(
                'daq: the file backend needs file_path (a CSV, NPZ, MAT or TDMS recording)'
            )
        path = Path(cfg['file_path'])
        mapping = (
            ImportMapping.from_dict(load_mapping(cfg['file_mapping']))
            if cfg['file_mapping']
            else {}
        )
        recording = read_lab_file(path, mapping)
        self.response = next(
            channel
            for channel in RESPONSE_CHANNELS
            if channel.quantity == recording.response_quantity
        )
        self.force_n = recording.force_n
        self.velocity_m_s = recording.response
        self.sample_rate_hz = recording.sample_rate_hz
        self.force_full_scale = recording.full_scale_force_n
        self.velocity_full_scale = recording.full_scale_response
        self._path, self._loop, self._publish = path, cfg['loop'], publish
        self._batch = PacedSource.paced_batch(
            cfg, self.sample_rate_hz, cfg['batch_size'], cfg['rate_factor']
        )
        self.next_index = 0
        self.finished = False
        batches_per_s = self.sample_rate_hz * cfg['rate_factor'] / self._batch
        self.source = PacedSource(
            node,
            node.publishers_of_samples,
            cfg,
            batches_per_s=batches_per_s,
            window_samples=PacedSource.window_samples(cfg, self.sample_rate_hz, self._batch),
            pace_label=f'x{cfg["rate_factor"]:g} the file rate',
            release=self._on_tick,
            sample_rate_hz=self.sample_rate_hz,
        )
        node.health.add(
            'source',
            lambda: self.source.status(self.sample_rate_hz, cfg['rate_factor']),
        )
        self._log = node.get_logger()
        self._timer = node.create_timer(1.0 / batches_per_s, self._on_tick)

    def describe(self) -> str:
        """One line for the start-up log."""
        return f'{self._path}: {self.force_n.size} samples at {self.sample_rate_hz:g} Hz' + (
            ', looping' if self._loop else ''
        )

    def _on_tick(self) -> None:
        if not self.source.ready():
            return
        for _ in range(self.source.due(self._batch)):
            position = self.next_index % self.force_n.size if self._loop else self.next_index
            if position >= self.force_n.size:
                if not self.finished:
                    self.finished = True
                    self._log.info(f'{self._path} streamed to its end')
                return
            stop = min(position + self._batch, self.force_n.size)
            self._publish(
                self.next_index, self.force_n[position:stop], self.velocity_m_s[position:stop]
            )
            self.next_index += stop - position
            self.source.sent(self.next_index)

    def close(self) -> None:
        """Nothing is held open: the file was read at start-up."""


def main(args: list[str] | None = None) -> int:
    """`ros2 run fmm_ros daq --ros-args -p backend:=nidaqmx|file ...`."""
    return run_node(Daq, args)


if __name__ == '__main__':
    main()
