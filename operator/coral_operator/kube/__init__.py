"""The only layer that talks to the Kubernetes API (reads and writes through the official client)."""
