"""Test and demo tooling: kind clusters whose workers are robots, a local Kubernetes control plane
with kwok robots, images built from the repository's Dockerfiles, and missions on them."""
