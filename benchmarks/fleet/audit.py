"""Counting API requests per client from the kube-apiserver's audit log.

`bench_fleet` starts the apiserver with `audit_flags(...)`; every completed request is one JSON
line with its user agent, so requests can be attributed to the DaemonSet controller, the scheduler
or the Coral operator without touching either. Lease renewals and non-resource URLs are left out
of the log: they are kwok's heartbeat and health probes, the same in both runs.
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Callable
from pathlib import Path

POLICY = """apiVersion: audit.k8s.io/v1
kind: Policy
omitStages: ["RequestReceived", "ResponseStarted"]
rules:
- level: None
  resources:
  - group: coordination.k8s.io
    resources: ["leases"]
- level: None
  nonResourceURLs: ["/*"]
- level: Metadata
"""


def audit_flags(folder: Path) -> tuple[list[str], Path]:
    """kube-apiserver flags writing the audit log into `folder`, and the log's path."""
    folder.mkdir(parents=True, exist_ok=True)
    policy = folder / "audit-policy.yaml"
    policy.write_text(POLICY)
    log = folder / "audit.log"
    return [
        f"--audit-policy-file={policy}",
        f"--audit-log-path={log}",
        "--audit-log-format=json",
        "--audit-log-maxsize=100000",  # MB; 0 would mean the default of 100 MB and rotation
        "--audit-log-mode=batch",
        "--audit-log-batch-max-wait=1s",
    ], log


class AuditLog:
    """Reads the audit log incrementally: `count_since_mark` attributes lines written after `mark`."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.offset = 0

    def mark(self) -> None:
        self.offset = self.path.stat().st_size if self.path.exists() else 0

    def count_since_mark(self, classify: Callable[[dict], str | None]) -> Counter[str]:
        counts: Counter[str] = Counter()
        with self.path.open("rb") as stream:
            stream.seek(self.offset)
            for line in stream:
                try:
                    event = json.loads(line)
                except ValueError:
                    continue
                key = classify(event)
                if key:
                    counts[key] += 1
        return counts


def request_kind(event: dict) -> str:
    """`verb resource[/subresource]` of an audit event, for the per-client breakdown."""
    ref = event.get("objectRef") or {}
    resource = ref.get("resource", "?") + (f"/{ref['subresource']}" if ref.get("subresource") else "")
    return f"{event.get('verb', '?')} {resource}"


def client_and_kind(event: dict) -> str:
    """`client: verb resource` of any request: the whole control plane's share of a run."""
    agent = (event.get("userAgent") or "?").split("/", 1)[0]
    return f"{agent}: {request_kind(event)}"


def classify(event: dict) -> str | None:
    """Which client made a request: `daemonset`, `scheduler`, `operator`, or None for the rest."""
    agent = event.get("userAgent") or ""
    user = (event.get("user") or {}).get("username", "")
    if "daemon-set-controller" in agent or user.endswith(":daemon-set-controller"):
        return "daemonset"
    if user == "system:kube-scheduler":
        return "scheduler"
    if agent.startswith(("coral-bench", "kwok", "kubectl")):
        return None
    # The operator runs with the admin kubeconfig, like the benchmark, kubectl and kwok (told apart above).
    if user.endswith("admin") and agent.startswith(("kopf", "coral-operator", "Python")):
        return "operator"
    return None
