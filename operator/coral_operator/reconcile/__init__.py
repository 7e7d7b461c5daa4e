"""The reconcilers: one level-based pass per CoralSystem and per CoralInstance, run from one work queue.

See docs/architecture.md for the data path and the layers.
"""
