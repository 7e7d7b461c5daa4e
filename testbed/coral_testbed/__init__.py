"""Test and demo tooling: a local Kubernetes control plane with kwok robots, and the robot runner."""
