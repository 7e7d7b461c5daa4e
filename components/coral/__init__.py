"""Robot-side Coral runtime: behavior-tree engine, component SDK, executor and local runtime."""

__version__ = "0.1.0"
