"""Kubeconfig files for the local control plane: one per client identity, certificates by path.

Built as plain dictionaries (pure, testable) and written as YAML by `controlplane.start`. The
admin kubeconfig is the one users, tests and the operator get.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

CONTEXT = "coral-dev"


def build_kubeconfig(
    server: str, ca_cert: Path, client_cert: Path, client_key: Path, user: str
) -> dict[str, Any]:
    return {
        "apiVersion": "v1",
        "kind": "Config",
        "clusters": [{"name": CONTEXT, "cluster": {"server": server, "certificate-authority": str(ca_cert)}}],
        "users": [
            {"name": user, "user": {"client-certificate": str(client_cert), "client-key": str(client_key)}}
        ],
        "contexts": [{"name": CONTEXT, "context": {"cluster": CONTEXT, "user": user}}],
        "current-context": CONTEXT,
    }


def write_kubeconfig(path: Path, config: dict[str, Any]) -> Path:
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    path.chmod(0o600)
    return path


def read_current_context(path: Path) -> tuple[str, str]:
    """Returns (context name, server URL) of a kubeconfig, for refusing unknown clusters.

    Raises:
        ValueError: naming the file and what is missing.
    """
    try:
        config = yaml.safe_load(path.read_text()) or {}
    except (OSError, yaml.YAMLError) as error:
        raise ValueError(f"{path}: cannot read kubeconfig: {error}") from error
    name = config.get("current-context")
    if not name:
        raise ValueError(f"{path}: no current-context")
    contexts = {c.get("name"): c.get("context", {}) for c in config.get("contexts") or []}
    if name not in contexts:
        raise ValueError(f"{path}: current-context {name!r} is not in contexts")
    clusters = {c.get("name"): c.get("cluster", {}) for c in config.get("clusters") or []}
    server = clusters.get(contexts[name].get("cluster"), {}).get("server", "")
    return name, server
