"""Bag I/O without ROS: rosbag2 bags (MCAP or sqlite3) written and read with rosbags."""
