"""kopf glue only: importing this package registers the indexes, the watch handlers and the settings.

The operator's logic lives in `reconcile/` (passes), `planning/` (decisions) and `kube/` (API
calls); see docs/architecture.md.
"""

from coral_operator.handlers import indexing, settings, watching

__all__ = ["indexing", "settings", "watching"]
