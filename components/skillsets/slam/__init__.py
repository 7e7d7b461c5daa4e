"""SLAM skillset: KISS-ICP LiDAR odometry and mapping, exported as behaviors."""
