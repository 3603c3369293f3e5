"""The thin ROS 2 shell around the core; nothing numerical lives here.

Nodes (`nodes`), message conversion (`msgs`), parameter tables (`params`; the package's
params file, above the nodes, in `params_file`), the QoS profiles (`qos`), the rig's
parameters and the `ros2 run` entry (`common`), flow control of the sample streams (`flow`),
the launch-free graph (`graph`), the launcher (`launch`) and the demo session (`demo`).
"""
