"""Files in and out, without ROS.

rosbag2 bags (`bags`), lab measurement files (`labfiles`) and FRF exchange files (`frf_files`:
UFF 58, CSV, JSON).
"""
