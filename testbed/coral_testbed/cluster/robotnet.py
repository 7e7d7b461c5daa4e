"""Real robots' network: one bridge per cluster, one network namespace per robot on it.

Used by `realrobots`. Layout of one cluster (slot S, recorded in its state, so `down` removes
exactly what `up` made):

    host:     bridge crk<S>br, 10.<160+S>.0.1/24 (multicast snooping off: DDS discovery floods)
    robot i:  netns crk<S>-<robot>; veth crk<S>h<i> (on the bridge) <-> eth0 10.<160+S>.0.<i+2>/24,
              lo up, default route via the bridge address; pods off the host network get
              10.<160+S>.<i+1>.0/24 from the robot's own CNI bridge

The host side carries an address only so the API server can reach the kubelets (logs, exec);
nothing listens on it. `set_link(robot, False)` sets the robot's bridge-side veth down: every
packet to and from the robot is lost, as when it drives out of Wi-Fi range.
"""

from __future__ import annotations

import fcntl
import ipaddress
import os
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

SLOTS = range(32)
_PREFIX = "crk"
_LOCK = Path("/run/coral-dev-cluster/slots.lock")


class NetworkError(RuntimeError):
    """An `ip` command failed; the message has the command and its stderr."""


# iproute2's `ip` rather than pyroute2: each step is a command a person can rerun by hand to look
# at or undo a robot's network, and a failure quotes it.
def ip(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    result = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30, check=False)
    if check and result.returncode != 0:
        raise NetworkError(f"`ip {' '.join(args)}` exited with {result.returncode}: {result.stderr.strip()}")
    return result


def namespaces_supported() -> bool:
    """True when this process may create network namespaces (root and `ip` installed)."""
    return os.geteuid() == 0 and shutil.which("ip") is not None and Path("/proc/self/ns/net").exists()


def bridge_name(slot: int) -> str:
    return f"{_PREFIX}{slot}br"


def netns_name(slot: int, robot: str) -> str:
    return f"{_PREFIX}{slot}-{robot}"


def host_veth(slot: int, index: int) -> str:
    return f"{_PREFIX}{slot}h{index}"


def subnet(slot: int) -> ipaddress.IPv4Network:
    return ipaddress.IPv4Network(f"10.{160 + slot}.0.0/24")


def gateway_address(slot: int) -> str:
    return str(subnet(slot).network_address + 1)


def robot_address(slot: int, index: int) -> str:
    """Address of the robot with this index (0-based); .1 is the bridge."""
    if not 0 <= index < 253:
        raise ValueError(f"robot index {index} is out of range: at most 253 real robots per cluster")
    return str(subnet(slot).network_address + 2 + index)


def pod_subnet(slot: int, index: int) -> str:
    return f"10.{160 + slot}.{index + 1}.0/24"


def _links() -> str:
    return ip("-o", "link", "show", check=False).stdout


def _namespaces() -> list[str]:
    return [line.split(" ")[0] for line in ip("netns", "list", check=False).stdout.splitlines() if line]


def slot_resources(slot: int) -> list[str]:
    """Names of this slot's namespaces and links that exist now (empty once all are removed)."""
    found = [name for name in _namespaces() if name.startswith(f"{_PREFIX}{slot}-")]
    found += re.findall(rf"^\d+: ({_PREFIX}{slot}(?:h\d+|br))[@:]", _links(), flags=re.MULTILINE)
    return found


def robot_resources(link: RobotLink) -> list[str]:
    """The robot's namespace and bridge-side link, those that exist now (empty once removed)."""
    found = [name for name in _namespaces() if name == link.netns]
    if re.search(rf"^\d+: {link.host_veth}[@:]", _links(), flags=re.MULTILINE):
        found.append(link.host_veth)
    return found


def claim_slot() -> int:
    """A slot with no bridge yet, whose bridge is created before the lock is released."""
    _LOCK.parent.mkdir(parents=True, exist_ok=True)
    with _LOCK.open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        taken = set(re.findall(rf"^\d+: {_PREFIX}(\d+)br[@:]", _links(), flags=re.MULTILINE))
        for slot in SLOTS:
            if str(slot) not in taken:
                create_bridge(slot)
                return slot
    raise NetworkError(
        f"every real-robot network slot ({len(SLOTS)}) is in use; run `coral dev-cluster local down`"
    )


def create_bridge(slot: int) -> None:
    bridge = bridge_name(slot)
    ip("link", "add", bridge, "type", "bridge", "mcast_snooping", "0")
    ip("addr", "add", f"{gateway_address(slot)}/{subnet(slot).prefixlen}", "dev", bridge)
    ip("link", "set", bridge, "up")


@dataclass(frozen=True)
class RobotLink:
    """One robot's place on the network."""

    robot: str
    slot: int
    index: int

    @property
    def netns(self) -> str:
        return netns_name(self.slot, self.robot)

    @property
    def address(self) -> str:
        return robot_address(self.slot, self.index)

    @property
    def host_veth(self) -> str:
        return host_veth(self.slot, self.index)

    @property
    def netns_path(self) -> Path:
        return Path("/run/netns") / self.netns


def add_robot(link: RobotLink) -> None:
    """Creates the robot's namespace and plugs it into the bridge (replacing leftovers of the same name)."""
    remove_robot(link)
    ns, host, peer = link.netns, link.host_veth, f"{_PREFIX}{link.slot}p{link.index}"
    ip("netns", "add", ns)
    ip("link", "add", host, "type", "veth", "peer", "name", peer)
    ip("link", "set", peer, "netns", ns)
    ip("link", "set", host, "master", bridge_name(link.slot))
    ip("link", "set", host, "up")
    ip("-n", ns, "link", "set", peer, "name", "eth0")
    ip("-n", ns, "addr", "add", f"{link.address}/{subnet(link.slot).prefixlen}", "dev", "eth0")
    ip("-n", ns, "link", "set", "lo", "up")
    ip("-n", ns, "link", "set", "eth0", "multicast", "on")
    ip("-n", ns, "link", "set", "eth0", "up")
    ip("-n", ns, "route", "add", "default", "via", gateway_address(link.slot))


def route_api_service(link: RobotLink, service_ip: str, api_port: int) -> None:
    """Sends the `kubernetes` Service (service_ip:443) to the uplink's 127.0.0.1:api_port inside the robot.

    There is no kube-proxy; this one rule per robot gives pods the in-cluster API address that
    their ServiceAccount clients use (the server certificate names service_ip). Pods on the
    robot's bridge arrive through PREROUTING, host-network pods through OUTPUT; a loopback
    destination from the bridge needs route_localnet, set in the robot's namespace only.
    """
    ns = ["ip", "netns", "exec", link.netns]
    _run([*ns, "sysctl", "-q", "-w", "net.ipv4.conf.all.route_localnet=1"])
    for chain in ("PREROUTING", "OUTPUT"):
        _run(
            [
                *ns,
                "iptables",
                "-w",
                "-t",
                "nat",
                "-A",
                chain,
                "-d",
                f"{service_ip}/32",
                "-p",
                "tcp",
                "--dport",
                "443",
                "-j",
                "DNAT",
                "--to-destination",
                f"127.0.0.1:{api_port}",
            ]
        )


def _run(argv: list[str]) -> None:
    result = subprocess.run(argv, capture_output=True, text=True, timeout=30, check=False)
    if result.returncode != 0:
        raise NetworkError(f"`{' '.join(argv)}` exited with {result.returncode}: {result.stderr.strip()}")


def set_link(link: RobotLink, up: bool) -> None:
    ip("link", "set", link.host_veth, "up" if up else "down")


def link_is_up(link: RobotLink) -> bool:
    out = ip("-o", "link", "show", link.host_veth, check=False).stdout
    return "state UP" in out or ("<" in out and ",UP" in out.split(">")[0])


def remove_robot(link: RobotLink) -> None:
    """Deletes the robot's namespace and veth (a no-op when they do not exist)."""
    if link.netns in _namespaces():
        ip("netns", "delete", link.netns, check=False)
    if re.search(rf"^\d+: {link.host_veth}[@:]", _links(), flags=re.MULTILINE):
        ip("link", "delete", link.host_veth, check=False)


def remove_bridge(slot: int) -> None:
    if re.search(rf"^\d+: {bridge_name(slot)}[@:]", _links(), flags=re.MULTILINE):
        ip("link", "delete", bridge_name(slot), check=False)
