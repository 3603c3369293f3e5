"""ROS 2 nodes: each module holds one node class and a `main()` for `ros2 run fmm_ros <node>`."""
