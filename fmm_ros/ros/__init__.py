"""The thin ROS 2 shell around the core; nothing numerical lives here.

Nodes (`nodes`), message conversion (`msgs`), parameter tables (`params`), QoS and the
`ros2 run` entry (`common`), the launch-free graph (`graph`), the launcher (`launch`) and the
demo session (`demo`).
"""
