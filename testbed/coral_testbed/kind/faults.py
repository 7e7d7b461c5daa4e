"""Robot faults on a kind cluster, made through the robot's node container as on real hardware.

A robot is the kind worker labelled `coral.dev/robot=<name>`; its container has the Node's name.
Each fault acts on that container only: its kubelet or containerd (systemd inside the node), its
link to the cluster's network, or the whole machine. Called by the CLI and the tests.
"""

from __future__ import annotations

import subprocess

from coral_testbed.cluster import binaries
from coral_testbed.kind import clusters, offlineagent


class FaultError(RuntimeError):
    """The robot is unknown or the fault could not be made; the message says which."""


def node_of(running: clusters.Running, robot: str) -> str:
    """The node container of `robot`: the Node labelled coral.dev/robot=<robot> (same name)."""
    done = _kubectl(running, "get", "nodes", "-l", f"{clusters.ROBOT_LABEL}={robot}", "-o", "name")
    names = [line.removeprefix("node/") for line in done.stdout.split()]
    if done.returncode != 0 or len(names) != 1 or names[0] not in running.node_containers():
        raise FaultError(
            f"no robot {robot!r} among the nodes of kind cluster {running.name}: {done.stderr.strip()}"
        )
    return names[0]


def _exec(running: clusters.Running, robot: str, *argv: str) -> None:
    running.engine.docker("exec", node_of(running, robot), *argv)


def stop_kubelet(running: clusters.Running, robot: str) -> None:
    """The robot's kubelet stops; its containers keep running and its Node goes NotReady (~40 s)."""
    _exec(running, robot, "systemctl", "stop", "kubelet")


def start_kubelet(running: clusters.Running, robot: str) -> None:
    """Starts the robot's stopped kubelet again; its Node reports Ready within seconds."""
    _exec(running, robot, "systemctl", "start", "kubelet")


def kill_containerd(running: clusters.Running, robot: str) -> None:
    """SIGKILL to the robot's containerd; systemd restarts it (Restart=always), the pods' shims survive."""
    _exec(running, robot, "systemctl", "kill", "--signal=SIGKILL", "containerd")


def _kubectl(running: clusters.Running, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [binaries.find_kubectl(None), *args], env=running.env(), capture_output=True, text=True, timeout=30
    )


def cut_link(running: clusters.Running, robot: str) -> None:
    """Disconnects the robot's node from the cluster's network: no traffic to the API server, the
    registry or other robots."""
    running.engine.docker(
        "network", "disconnect", clusters.network_name(running.name), node_of(running, robot)
    )


def robot_address(running: clusters.Running, robot: str) -> str:
    """The robot's Node's InternalIP: the address its kubelet serves on and the cluster reaches it at
    (kept while its link is cut)."""
    return _internal_ip(running, node_of(running, robot))


def _internal_ip(running: clusters.Running, node: str) -> str:
    done = _kubectl(
        running, "get", "node", node, "-o", 'jsonpath={.status.addresses[?(@.type=="InternalIP")].address}'
    )
    if done.returncode != 0 or not done.stdout.strip():
        raise FaultError(f"no InternalIP for node {node!r}: {done.stderr.strip()}")
    return done.stdout.strip()


def restore_link(running: clusters.Running, robot: str) -> None:
    """Reconnects the robot's node at its Node's InternalIP, the address its kubelet serves on."""
    container = node_of(running, robot)
    address = _internal_ip(running, container)
    running.engine.docker(
        "network", "connect", f"--ip={address}", clusters.network_name(running.name), container
    )


def power_cycle(running: clusters.Running, robot: str) -> None:
    """Restarts the robot's node container: every process in it starts again from boot."""
    running.engine.docker("restart", node_of(running, robot), timeout=180)


def cut_power(running: clusters.Running, robot: str) -> None:
    """SIGKILL to the robot's node container, as pulling its plug: no shutdown, every process gone.
    The container (its disk) stays, so `restore_power` boots the same robot again."""
    running.engine.docker("kill", node_of(running, robot), timeout=60)


def restore_power(running: clusters.Running, robot: str) -> None:
    """Boots the robot's node container that `cut_power` stopped."""
    # The Node keeps its name and label while the container is down, so it is still found by them.
    running.engine.docker("start", node_of(running, robot), timeout=180)


_RUNTIME = ("kubelet.slice", "containerd.service", offlineagent.UNITS[1])
"""What runs the robot's pods: the kubelet and every pod's containers (kind's kubelet.slice),
containerd with its shims, the offline agent."""
_BOOT = ("containerd.service", *offlineagent.UNITS, "kubelet.service")
"""What the node's init system starts at boot, in the order its units give."""


def reboot_in_place(running: clusters.Running, robot: str) -> None:
    """Power lost and back inside the robot's node container, its link left as it is: SIGKILL to
    the kubelet, every container, containerd and its shims and the offline agent at once; then the
    boot the node's systemd does (containerd, the agent's boot step, the kubelet, the agent).

    The power cycle of a robot cut off: `power_cycle` restarts the container, and a node container
    restarted without its network stops in kind's entrypoint (no address for its own name)."""
    node = node_of(running, robot)
    # Stopping the killed units at once cancels their restarts (1 s away): nothing starts before
    # the boot below, as nothing runs on a robot without power.
    script = (
        f"systemctl kill --signal=SIGKILL {' '.join(_RUNTIME)}; "
        f"systemctl stop {' '.join(_RUNTIME)} {offlineagent.UNITS[0]}; "
        f"systemctl start {' '.join(_BOOT)}"
    )
    running.engine.docker("exec", node, "bash", "-c", script, timeout=180)
