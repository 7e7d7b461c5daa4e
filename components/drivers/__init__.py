"""Reference Coral drivers (each folder holds one driver and its Dockerfile)."""
