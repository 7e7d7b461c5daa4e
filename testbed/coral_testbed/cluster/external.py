"""Using a cluster given by $KUBECONFIG (a kind cluster, say) instead of the local control plane.

Called by the pytest `cluster` fixture. Tests create namespaces and Nodes, so only clusters that
are plainly disposable are accepted: kind clusters (context `kind-*`), the local dev cluster
(context `coral-dev`), and contexts listed in $CORAL_TEST_CONTEXTS.
"""

from __future__ import annotations

import os
from pathlib import Path

from coral_testbed.cluster import kubeconfigs

ALLOW_ENV = "CORAL_TEST_CONTEXTS"


class RefusedCluster(RuntimeError):
    """The kubeconfig points at a cluster tests must not touch."""


def is_disposable(context: str, allowed: str = "") -> bool:
    """True for kind and dev-cluster contexts, and for those in the comma-separated `allowed`."""
    extra = {name.strip() for name in allowed.split(",") if name.strip()}
    return context.startswith("kind-") or context == kubeconfigs.CONTEXT or context in extra


def runs_own_kwok(context: str) -> bool:
    """True for a `coral dev-cluster`, which already runs kwok (a second one would fight over robots)."""
    return context == kubeconfigs.CONTEXT


def kubeconfig_from_env(value: str) -> Path:
    """The single kubeconfig file named by a $KUBECONFIG value.

    Raises:
        RefusedCluster: the value lists several files or names a missing one.
    """
    paths = [p for p in value.split(os.pathsep) if p]
    if len(paths) != 1:
        raise RefusedCluster(f"KUBECONFIG={value!r}: give exactly one kubeconfig file for the test cluster")
    path = Path(paths[0]).expanduser()
    if not path.is_file():
        raise RefusedCluster(f"KUBECONFIG={value!r}: no such file")
    return path


def check_disposable(kubeconfig: Path) -> str:
    """Returns the current context of `kubeconfig` if tests may use it.

    Raises:
        RefusedCluster: naming the context and how to allow it.
    """
    context, server = kubeconfigs.read_current_context(kubeconfig)
    if not is_disposable(context, os.environ.get(ALLOW_ENV, "")):
        raise RefusedCluster(
            f"{kubeconfig}: refusing to run tests against context {context!r} ({server}); tests create and "
            f"delete namespaces and Nodes. Unset KUBECONFIG to use the local control plane, or add the "
            f"context to ${ALLOW_ENV} if the cluster is disposable"
        )
    return context
