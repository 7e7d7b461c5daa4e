"""Test and demo tooling: a local Kubernetes control plane with real robots (an upstream kubelet and
containerd each) and kwok robots, images built from the repository's Dockerfiles, and missions on it."""
