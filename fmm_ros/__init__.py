"""fmm_ros: impact-hammer FRF testing and friction identification on the friction measuring machine.

Each folder is one kind of thing (ARCHITECTURE.md has the map):

- `fmm_ros.core`: ROS-free numerics, by stage: `physics` (the oscillator of Eq. 3 and its
  terms), `signal` (impact capture, flags, impulse, FRFs, level averages), `identify` (fitting
  mu, damping and model terms; rig identification), `diagnose` (what the model misses).
- `fmm_ros.io`: files: rosbag2 bags, lab files, FRF exchange files.
- `fmm_ros.sim`: synthetic data: hammer sessions, simulated bags, hidden-effect cases.
- `fmm_ros.workflows`: pipelines over the core (bag replay, analyse -> fit -> diagnose).
- `fmm_ros.report`: figures and the HTML page; draws what the workflows computed.
- `fmm_ros.ros`: the thin ROS 2 shell (nodes, messages, parameters, graph, launcher, demo).
- `fmm_ros.cli`: the `fmm` command.
- `fmm_ros.constants`: every named constant the layers share.
"""

__version__ = '0.1.0'
