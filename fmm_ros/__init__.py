"""fmm_ros: impact-hammer FRF testing and friction identification on the friction measuring machine.

`fmm_ros.core` is ROS-free (numpy/scipy): physics, signals, fitting, diagnosis, bag I/O.
`fmm_ros.nodes` and `fmm_ros.msgs` are the thin ROS 2 shell around it.
"""

__version__ = '0.1.0'
