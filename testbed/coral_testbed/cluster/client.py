"""`Cluster`: one handle on a Kubernetes cluster for tests, the demo and tooling.

The pytest `cluster` fixture yields one (for the local control plane, or for the cluster named by
$KUBECONFIG); other engineers' tests and the operator's test harness use it to reach the API with
the Python client, run the pinned kubectl as a user would, and manage simulated robots.
"""

from __future__ import annotations

import os
import subprocess
from functools import cached_property
from pathlib import Path

from kubernetes import client as k8s
from kubernetes import config as k8s_config

from coral_testbed.cluster import binaries, robots


def parse_table(text: str) -> dict[str, dict[str, str]]:
    """kubectl's column output (`get ... -o wide`) as {first column: {header: value}}.

    Columns are cut at the header's word positions, so values with spaces (OS-IMAGE) stay whole.
    """
    header, *lines = text.splitlines()
    starts = [i for i, char in enumerate(header) if char != " " and (i == 0 or header[i - 1] == " ")]
    names = header.split()
    rows = {}
    for line in lines:
        cells = [line[a:b].strip() for a, b in zip(starts, [*starts[1:], None], strict=True)]
        rows[cells[0]] = dict(zip(names, cells, strict=True))
    return rows


class KubectlError(subprocess.CalledProcessError):
    """A kubectl command failed; unlike its base class, the message includes kubectl's stderr."""

    def __str__(self) -> str:
        command = " ".join(self.cmd) if isinstance(self.cmd, list) else str(self.cmd)
        return f"`{command}` exited with {self.returncode}: {(self.stderr or '').strip()}"


class Cluster:
    """A cluster reachable through `kubeconfig`.

    Attributes:
        kubeconfig: admin kubeconfig file.
        bin_dir: the pinned binaries that run the local control plane, None for external clusters.
        is_local: True for the control plane this project started itself.
        state_dir: the local control plane's state folder (its logs, the audit log), None for
            external clusters.
    """

    def __init__(
        self, kubeconfig: Path, bin_dir: Path | None, is_local: bool, state_dir: Path | None = None
    ) -> None:
        self.kubeconfig = Path(kubeconfig)
        self.bin_dir = bin_dir
        self.is_local = is_local
        self.state_dir = state_dir
        self._kubectl = binaries.find_kubectl(bin_dir)

    @classmethod
    def from_dev_cluster(cls, state_dir: Path | None = None) -> Cluster:
        """The control plane that `coral dev-cluster local up` (or `controlplane.start`) runs from
        `state_dir`.

        Raises:
            ControlPlaneError: nothing runs from that folder.
        """
        from coral_testbed.cluster import controlplane

        folder = (state_dir or controlplane.default_state_dir()).resolve()
        state = controlplane.load_state(folder)
        if state is None or not state.alive():
            raise controlplane.ControlPlaneError(
                f"no control plane is running from {folder}; start one with `coral dev-cluster local up`"
            )
        return cls(state.kubeconfig, state.layout.bin_dir, is_local=True, state_dir=folder)

    def __repr__(self) -> str:
        return f"Cluster(kubeconfig={str(self.kubeconfig)!r}, is_local={self.is_local})"

    @cached_property
    def api_client(self) -> k8s.ApiClient:
        return k8s_config.new_client_from_config(config_file=str(self.kubeconfig))

    def close(self) -> None:
        if "api_client" in self.__dict__:
            self.api_client.close()
            del self.__dict__["api_client"]

    def env(self) -> dict[str, str]:
        """This process's environment pointed at the cluster, with the pinned tools first on PATH."""
        tools = str(self.bin_dir) if self.bin_dir is not None else str(Path(self._kubectl).parent)
        return {
            **os.environ,
            "KUBECONFIG": str(self.kubeconfig),
            "PATH": tools + os.pathsep + os.environ.get("PATH", ""),
        }

    def kubectl(
        self, *args: str, input: str | None = None, check: bool = True, timeout: float = 60
    ) -> subprocess.CompletedProcess[str]:
        """Runs kubectl against this cluster, as a user would type it.

        Raises:
            KubectlError: `check` is set and kubectl failed (the message has its stderr).
        """
        argv = [self._kubectl, *args]
        result = subprocess.run(
            argv, input=input, capture_output=True, text=True, timeout=timeout, env=self.env(), check=False
        )
        if check and result.returncode != 0:
            raise KubectlError(result.returncode, ["kubectl", *args], result.stdout, result.stderr)
        return result

    def add_robots(
        self, names: list[str], labels: dict[str, str] | None = None, timeout: float = 120
    ) -> None:
        """Creates kwok robot Nodes, or merges `labels` into existing ones; waits until new ones are Ready."""
        created = robots.apply_robots(self.api_client, names, labels)
        robots.wait_robots_ready(self.api_client, created, timeout=timeout)

    def remove_robots(self, names: list[str]) -> None:
        robots.delete_robots(self.api_client, names)

    def set_robot_ready(self, name: str, ready: bool) -> None:
        """Makes a robot report Ready=True or Ready=False (reachable, lease renewed) and waits for it."""
        robots.apply_robot_ready(self.api_client, name, ready)

    def set_robot_reachable(self, name: str, reachable: bool) -> None:
        """Takes a robot off the network (its lease lapses, Ready becomes Unknown) or back, and waits.

        Going offline takes the controller manager's node-monitor grace period (30 s on a developer's
        local control plane, 12 s on a test session's, 50 s by default elsewhere).
        """
        robots.apply_robot_reachable(self.api_client, name, reachable)
