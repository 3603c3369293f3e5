"""ROS-free core of fmm_ros: importable and testable with numpy and scipy alone."""
