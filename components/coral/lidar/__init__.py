"""Synthetic LiDAR data: indoor scenes, a spinning multi-beam sensor, ROS 2 bags with ground truth."""
