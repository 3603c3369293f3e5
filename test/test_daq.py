"""daq node: the file backend streams a lab recording into the analyzer; nidaqmx fails clearly."""

import sys

import numpy as np
import pytest
from accelerometer_records import session, write_csv
from rclpy.node import Node
from rig_graph import FAST_ANALYZER, Listener, params, wait_for

from fmm_interfaces.srv import FitFriction
from fmm_ros.constants import FIT_SERVICE
from fmm_ros.core.signal.records import write_impact_csv
from fmm_ros.ros.flow import PacedSource
from fmm_ros.ros.nodes.analyzer import Analyzer
from fmm_ros.ros.nodes.daq import Daq
from fmm_ros.ros.nodes.fitter import Fitter
from fmm_ros.sim.excitation import impact_record

pytestmark = pytest.mark.ros

RATE_HZ = 10_000.0


@pytest.mark.parametrize('suffix', ['.csv', '.npz'])
def test_file_backend_streams_a_recording_into_the_analyzer(ros_graph, tmp_path, suffix):
    hit = impact_record(
        1000.0,
        rng=3,
        duration_s=8.0,
        pretrigger_s=1.0,
        force_noise_std_n=0.2,
        velocity_noise_std_m_s=1e-4,
    )
    path = tmp_path / f'hit{suffix}'
    if suffix == '.csv':
        write_impact_csv(path, hit.force_n, hit.velocity_m_s, RATE_HZ)
    else:
        np.savez(path, force_n=hit.force_n, velocity_m_s=hit.velocity_m_s, sample_rate_hz=RATE_HZ)
    daq = ros_graph.add(
        Daq,
        parameter_overrides=params(
            backend='file', file_path=str(path), rate_factor=100.0, batch_size=1000
        ),
    )
    ros_graph.add(Analyzer, parameter_overrides=params(**FAST_ANALYZER))
    listener = ros_graph.add(Listener)
    ros_graph.start()
    assert wait_for(lambda: len(listener.impacts) == 1)
    (impact,) = listener.impacts
    assert (impact.level, impact.accepted) == ('medium', True)
    assert impact.impulse_n_s == pytest.approx(hit.impulse_n_s, rel=0.005)
    assert wait_for(lambda: daq.backend.finished)
    # 80,000 samples at x100: messages of the size the pace picks (max_batches_per_s a
    # second at most), a whole multiple of 1000 samples and larger than it
    size = PacedSource.paced_batch(daq.config, RATE_HZ, 1000, 100.0)
    assert size > 1000 and size % 1000 == 0
    assert daq.batches_published == -(-hit.force_n.size // size)


def test_file_backend_without_a_file_says_so(ros_graph):
    with pytest.raises(ValueError, match='needs file_path'):
        ros_graph.add(Daq, parameter_overrides=params(backend='file'))


def test_nidaqmx_backend_without_the_driver_says_what_to_install(ros_graph, monkeypatch):
    monkeypatch.setitem(sys.modules, 'nidaqmx', None)  # as on a machine without nidaqmx
    with pytest.raises(RuntimeError, match='pip install nidaqmx'):
        ros_graph.add(Daq)


@pytest.mark.slow
def test_an_accelerometer_session_streams_through_analyzer_and_fitter(ros_graph, tmp_path):
    """Acceleration on the response topic: flags on it, FRFs from it, mu from its integral."""
    mu = 0.113
    hits = session(mu, seed=4)
    path = write_csv(
        tmp_path / 'session.csv',
        np.concatenate([force for force, _ in hits]),
        np.concatenate([acceleration for _, acceleration in hits]),
    )
    ros_graph.add(
        Daq,
        parameter_overrides=params(
            backend='file', file_path=str(path), rate_factor=100.0, batch_size=1000
        ),
    )
    ros_graph.add(Analyzer, parameter_overrides=params(**FAST_ANALYZER))
    fitter = ros_graph.add(Fitter)
    listener = ros_graph.add(Listener)
    client = ros_graph.add(Node, node_name='caller').create_client(FitFriction, FIT_SERVICE)
    ros_graph.start()
    assert wait_for(lambda: len(fitter.impacts) == 3), f'{len(listener.impacts)} reported'
    assert all(impact.accepted for impact in listener.impacts), [
        tuple(impact.flags) for impact in listener.impacts
    ]
    response = ros_graph.call(client, FitFriction.Request(), timeout_s=120.0)
    assert response.success, response.message
    assert response.mu == pytest.approx(mu, rel=0.005)
