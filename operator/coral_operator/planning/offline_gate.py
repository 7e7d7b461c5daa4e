"""The operator's half of offline autonomy: the gate in front of a robot's pods (docs/offline.md).

When a system lets its robots run their last revision offline, each of its pods starts with a step
that takes the component's lock on the robot and lets it go at once. While an offline copy of the
component runs (a static pod the robot's agent wrote), its lock holder keeps the lock, so the API
server's copy starts only once the offline copy has stopped: never two drivers on one piece of
hardware. The label tells the robot's agent to record the pod, so that it can run it again offline.
Pure; called by `planning.pods`.
"""

from __future__ import annotations

import posixpath
from typing import Any

from coral_core import offline

from coral_operator.api.instance import CoralInstanceSpec


def _gate(lock: str, image: str) -> dict[str, Any]:
    return {
        "name": offline.GATE_CONTAINER,
        "image": image,
        # Blocks while the offline copy holds the lock; the lock is released when this step exits.
        "command": ["flock", posixpath.join(offline.LOCK_MOUNT, lock), "true"],
        "volumeMounts": [{"name": offline.LOCKS_VOLUME, "mountPath": offline.LOCK_MOUNT}],
        "securityContext": offline.lock_step_security(),
    }


def add_gate(
    *,
    spec: CoralInstanceSpec,
    namespace: str,
    part: str,
    pod_spec: dict[str, Any],
    labels: dict[str, str],
    image: str,
) -> dict[str, str]:
    """Puts the gate first in `pod_spec` and the offline label on `labels` (both in place) when the
    instance may run offline; returns the pod's offline annotations (none when it may not)."""
    if spec.offline is None:
        return {}
    lock = offline.lock_name(namespace, spec.system, part)
    pod_spec["initContainers"] = [_gate(lock, image), *pod_spec.get("initContainers", [])]
    pod_spec["volumes"] = [
        *pod_spec["volumes"],
        {"name": offline.LOCKS_VOLUME, "hostPath": {"path": offline.LOCKS_DIR, "type": "DirectoryOrCreate"}},
    ]
    labels[offline.LABEL_OFFLINE] = spec.offline.mode
    return {offline.ANNOTATION_INTERRUPT: str(spec.offline.interrupt_running_trees).lower()}
