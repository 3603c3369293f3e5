"""The names the live graph and its bags share: topics and the two sample channels' quantities.

Kept in the core (no ROS) because bag I/O reads and writes these topics without a ROS runtime.
"""

FORCE_TOPIC = '/fmm/force'
VELOCITY_TOPIC = '/fmm/velocity'
APPLIED_FORCE_TOPIC = '/fmm/sim/applied_force'
"""Simulation only: the force the hammer applies (noise-free), which drives rig_sim."""
IMPACTS_TOPIC = '/fmm/impacts'
FRF_TOPIC = '/fmm/frf'

# SampleBatch.quantity and SampleBatch.unit of the two channels.
FORCE = ('force', 'N')
VELOCITY = ('velocity', 'm/s')
