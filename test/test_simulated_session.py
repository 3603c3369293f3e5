"""The simulated session the replay tests and the offline benchmark are built on."""

import numpy as np

from fmm_ros.io.bags import BagReader
from fmm_ros.sim.session import simulated_session, write_session_bag


def test_a_session_is_one_continuous_record_of_hits_at_the_paper_levels(tmp_path):
    session = simulated_session(2, spacing_s=4.0, seed=1)
    assert session.hit_levels == ('low', 'low', 'medium', 'medium', 'high', 'high')
    assert session.duration_s == 24.1
    slot = 40_000
    for k, (start, peak) in enumerate(
        zip(session.hit_start_indices, session.hit_peak_force_n, strict=True)
    ):
        hit = session.force_n[k * slot : (k + 1) * slot]
        assert k * slot <= start < k * slot + 1_100
        # The pulse's peak, give or take where the samples fall and 0.05 N of noise.
        assert 0.99 * peak < hit.max() < peak + 0.5
        assert abs(peak - (450, 1000, 1450)[k // 2]) < 150
    # The rig moves after each hit and has come to rest before the next one.
    for k, start in enumerate(session.hit_start_indices):
        assert np.abs(session.velocity_m_s[start : start + 5_000]).max() > 0.01
        if k:
            assert np.abs(session.velocity_m_s[start - 2_000 : start - 1_000]).max() < 1e-4

    bag = write_session_bag(tmp_path / 'session', session)
    with BagReader(bag) as reader:
        batches = list(reader.batches())
    np.testing.assert_array_equal(np.concatenate([b.force for b in batches]), session.force_n)
    np.testing.assert_array_equal(
        np.concatenate([b.velocity for b in batches]), session.velocity_m_s
    )
