"""What one identity asked the local control plane and what it was answered, from its audit log.

The kube-apiserver that `controlplane.start` runs records every request of a ServiceAccount
(`components.AUDIT_POLICY`) in `Layout.audit_log`. Tests read it to compare what the operator really
does with what its chart grants (tests/integration/operator/test_helm_chart.py).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Request:
    """One request as RBAC sees it: a verb on a (group, resource[/subresource]), and its answer."""

    verb: str
    group: str
    resource: str
    namespace: str
    code: int

    @property
    def permission(self) -> tuple[str, str, str]:
        """(API group, resource, verb), as a Role rule grants it."""
        return self.group, self.resource, self.verb


def requests_of(log: Path, username: str) -> list[Request]:
    """Every resource request `username` made, in order (non-resource URLs such as /api left out)."""
    found = []
    # A rotated file (audit-<time>.log) holds the earlier requests.
    for path in sorted(log.parent.glob(f"{log.stem}-*{log.suffix}")) + [log]:
        if not path.exists():
            continue
        for line in path.read_text().splitlines():
            try:
                event = json.loads(line)
            except ValueError:
                continue  # a line cut by rotation
            if (event.get("user") or {}).get("username") != username:
                continue
            target = event.get("objectRef") or {}
            if not target.get("resource"):
                continue
            resource = target["resource"]
            if target.get("subresource"):
                resource = f"{resource}/{target['subresource']}"
            found.append(
                Request(
                    verb=event.get("verb", ""),
                    group=target.get("apiGroup", ""),
                    resource=resource,
                    namespace=target.get("namespace", ""),
                    code=int((event.get("responseStatus") or {}).get("code", 0)),
                )
            )
    return found
