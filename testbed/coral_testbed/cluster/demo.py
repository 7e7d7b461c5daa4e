"""What `make demo` shows for now: a control plane with robots, and a pod running on one of them.

Called by `coral dev-cluster local demo`. It uses a throwaway state folder, so it never disturbs a dev
cluster started with `coral dev-cluster local up`, and it stops every process it started, also on error.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from coral_testbed.cluster import controlplane
from coral_testbed.cluster.client import Cluster
from coral_testbed.waiting import wait_for

ROBOTS: dict[str, dict[str, str]] = {
    "robot-1": {"coral.dev/model": "turtlebot4"},
    "robot-2": {"coral.dev/model": "turtlebot4"},
    "robot-3": {"coral.dev/model": "spot"},
}
TARGET = "robot-3"

POD = f"""\
apiVersion: v1
kind: Pod
metadata:
  name: hello-robot
  namespace: default
spec:
  nodeSelector:
    coral.dev/robot: {TARGET}
  tolerations:
  - key: node.kubernetes.io/unreachable
    operator: Exists
    effect: NoExecute
  - key: node.kubernetes.io/not-ready
    operator: Exists
    effect: NoExecute
  containers:
  - name: hello
    image: registry.k8s.io/pause:3.10
"""


def run(echo: Callable[[str], None] = print) -> None:
    """Runs the demo from start to stop, echoing each step and each kubectl command with its output."""
    began = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="coral-demo-") as folder:
        state_dir = Path(folder)
        echo(
            "==> Starting a local control plane: etcd, kube-apiserver, kube-controller-manager,"
            " kube-scheduler, kwok"
        )
        try:
            state = controlplane.start(state_dir, progress=lambda line: echo(f"    {line}"))
            cluster = Cluster(state.kubeconfig, state.layout.bin_dir, is_local=True)
            _show(cluster, echo)
            cluster.close()
        finally:
            stopped = controlplane.stop(state_dir)
            echo(f"==> Stopped {len(stopped)} control-plane processes")
    echo(f"==> Demo finished in {time.monotonic() - began:.1f} s")


def _kubectl(cluster: Cluster, echo: Callable[[str], None], *args: str, input: str | None = None) -> str:
    echo(f"$ kubectl {' '.join(args)}")
    output = cluster.kubectl(*args, input=input).stdout.rstrip()
    echo(output)
    return output


def _show(cluster: Cluster, echo: Callable[[str], None]) -> None:
    echo(f"==> Creating robots {', '.join(ROBOTS)} (kwok Nodes labelled coral.dev/robot=<name>)")
    for name, labels in ROBOTS.items():
        cluster.add_robots([name], labels)
    _kubectl(cluster, echo, "get", "nodes", "-L", "coral.dev/robot,coral.dev/model")
    echo(f"==> Scheduling a pod pinned to {TARGET}")
    _kubectl(cluster, echo, "apply", "-f", "-", input=POD)

    def running() -> bool:
        phase = cluster.kubectl("get", "pod", "hello-robot", "-o", "jsonpath={.status.phase}").stdout
        return phase == "Running"

    wait_for(running, timeout=120, message="pod hello-robot to be Running")
    _kubectl(cluster, echo, "get", "pod", "hello-robot", "-o", "wide")
