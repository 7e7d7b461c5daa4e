"""Bag player driver: replays a ROS 2 bag at the recorded or a scaled rate, then exits (transient)."""
