"""The operator installed in the cluster by `helm install` of charts/coral-operator, from its image.

The operator's pod runs on a node that is not a robot (`OPERATOR_NODE_LABEL`), pulls
`coral.local/<operator repository>:<tag>` from the local registry like any robot image, and acts only
with the ServiceAccount and RBAC the chart creates. The image itself is built by
`coral_testbed.images`; this module only installs, finds and removes the release.
"""

from __future__ import annotations

import subprocess
from collections.abc import Collection
from dataclasses import dataclass, field
from pathlib import Path

from kubernetes import client as k8s

from coral_testbed.images import catalog
from coral_testbed.waiting import wait_for

OPERATOR_NODE_LABEL = "coral.dev/operator-node"
"""Label (value "true") of the non-robot nodes the operator's pod is scheduled onto."""

ROBOT_REGISTRY = "coral.local"
"""The registry name robots' containerds map to the local registry (docs/kind.md)."""

DEFAULT_RELEASE = "coral-operator"
DEFAULT_NAMESPACE = "coral-system"


class ChartInstallError(RuntimeError):
    """`helm install` failed, or the operator's pod did not become Ready (with its state)."""


def chart_dir() -> Path:
    from coral_testbed.images import building

    return building.find_repository_root() / "charts" / "coral-operator"


def operator_image() -> tuple[str, str]:
    """(repository, tag) of the operator image as robots and plain nodes pull it."""
    spec = catalog.by_name()["operator"]
    return f"{ROBOT_REGISTRY}/{spec.repository}", spec.tag


@dataclass(frozen=True)
class Release:
    """One install of the chart: what it is called and what it serves."""

    name: str = DEFAULT_RELEASE
    namespace: str = DEFAULT_NAMESPACE
    watch_namespaces: tuple[str, ...] = ()
    """Empty: every namespace (the chart's cluster-wide RBAC)."""
    policy: dict[str, tuple[str, ...]] = field(default_factory=dict)
    """Chart `policy.*` values to set, e.g. {"hostNetworkNamespaces": ("robots",)}."""
    helper_image: str = ""
    """The chart's `helperImage`; empty: the operator's own image."""

    def helm_values(self) -> list[str]:
        repository, tag = operator_image()
        values = [f"image.repository={repository}", f"image.tag={tag}"]
        if self.watch_namespaces:
            values.append(f"watchNamespaces={{{','.join(self.watch_namespaces)}}}")
        for key, items in sorted(self.policy.items()):
            values.append(f"policy.{key}={{{','.join(items)}}}")
        if self.helper_image:
            values.append(f"helperImage={self.helper_image}")
        # Helm reads dots in a --set key as nesting (the label's own are escaped), and "true" as a
        # boolean unless set as a string.
        selector = "nodeSelector." + OPERATOR_NODE_LABEL.replace(".", "\\.") + "=true"
        return [*(arg for value in values for arg in ("--set", value)), "--set-string", selector]


def _helm(helm: Path, env: dict[str, str], *args: str, timeout: float) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(helm), *args], env=env, capture_output=True, text=True, timeout=timeout, check=False
    )


def install(
    api: k8s.ApiClient, helm: Path, env: dict[str, str], release: Release, timeout: float = 240
) -> k8s.V1Pod:
    """Installs the chart and waits until the operator's pod is Ready; returns that pod.

    Raises:
        ChartInstallError: helm refused, or the pod was not Ready in time (the message has the
            pod's phase, container states and the release's Events).
    """
    result = _helm(
        helm,
        env,
        "install",
        release.name,
        str(chart_dir()),
        "-n",
        release.namespace,
        "--create-namespace",
        *release.helm_values(),
        timeout=120,
    )
    if result.returncode != 0:
        raise ChartInstallError(f"helm install {release.name}: {result.stderr.strip() or result.stdout}")
    return _ready_pod(api, release, timeout)


def upgrade(
    api: k8s.ApiClient, helm: Path, env: dict[str, str], release: Release, timeout: float = 240
) -> k8s.V1Pod:
    """`helm upgrade` of the installed release to `release`'s values (a changed policy, say): the
    operator's pod is replaced, as the policy is read at start-up. Returns the new pod once it is
    the only one and Ready.

    Raises:
        ChartInstallError: as `install`.
    """
    before = {pod.metadata.uid for pod in operator_pods(api, release)}
    result = _helm(
        helm,
        env,
        "upgrade",
        release.name,
        str(chart_dir()),
        "-n",
        release.namespace,
        *release.helm_values(),
        timeout=120,
    )
    if result.returncode != 0:
        raise ChartInstallError(f"helm upgrade {release.name}: {result.stderr.strip() or result.stdout}")
    return _ready_pod(api, release, timeout, replacing=before)


def _ready_pod(
    api: k8s.ApiClient, release: Release, timeout: float, replacing: Collection[str] = ()
) -> k8s.V1Pod:
    """The release's one Ready operator pod (not one of the pods `replacing`, nor beside them)."""
    core = k8s.CoreV1Api(api)

    def ready_pod() -> k8s.V1Pod | None:
        pods = operator_pods(api, release)
        if replacing and any(pod.metadata.uid in replacing for pod in pods):
            return None
        for pod in pods:
            conditions = {c.type: c.status for c in (pod.status.conditions or [])}
            if conditions.get("Ready") == "True" and pod.metadata.deletion_timestamp is None:
                return pod
        return None

    try:
        return wait_for(ready_pod, timeout=timeout, interval=1, message="the operator's pod to be Ready")
    except TimeoutError as error:
        raise ChartInstallError(f"{error}\n{describe(core, release)}") from error


def operator_pods(api: k8s.ApiClient, release: Release) -> list[k8s.V1Pod]:
    selector = f"app.kubernetes.io/instance={release.name}"
    return list(k8s.CoreV1Api(api).list_namespaced_pod(release.namespace, label_selector=selector).items)


def describe(core: k8s.CoreV1Api, release: Release) -> str:
    """The release's pods and the namespace's Events, for error messages."""
    lines = []
    for pod in core.list_namespaced_pod(release.namespace).items:
        states = [f"{s.name}: {s.state.to_dict()}" for s in (pod.status.container_statuses or [])]
        lines.append(f"pod {pod.metadata.name} on {pod.spec.node_name}: {pod.status.phase} {states}")
    for event in core.list_namespaced_event(release.namespace).items:
        lines.append(f"event {event.involved_object.name}: {event.reason}: {event.message}")
    return "\n".join(lines)


def uninstall(helm: Path, env: dict[str, str], release: Release) -> None:
    """Removes the release (the CRDs stay, as Helm keeps a chart's crds/); a missing one is fine."""
    result = _helm(helm, env, "uninstall", release.name, "-n", release.namespace, "--wait", timeout=120)
    if result.returncode != 0 and "not found" not in result.stderr:
        raise ChartInstallError(f"helm uninstall {release.name}: {result.stderr.strip()}")
