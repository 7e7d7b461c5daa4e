"""Per-robot network namespaces on one bridge, so traffic between simulated robots crosses a real link.

Used by `runner.RobotRunner`. Layout of one runner (slot N, claimed with a file lock so parallel
runners never collide and a crashed runner's leftovers are recognisable):

    root namespace:  bridge crr<N>br  10.<208+N>.0.1/16  (multicast snooping off: DDS discovery floods)
    robot i:         netns crr<N>-<robot>; veth crr<N>h<i> (on the bridge) <-> eth0 10.<208+N>.x.y/16,
                     lo up, default route via the bridge address

`cut_link` sets the robot's bridge-side veth down (every packet to and from the robot is lost, as
when a robot drives out of Wi-Fi range); `restore_link` sets it up again. When namespaces cannot be
made (not root, no `ip`), `Network.isolated` is False and robots share the host network: cuts then
only stop the robot's Kubernetes traffic (see docs/robot-runner.md).
"""

from __future__ import annotations

import fcntl
import ipaddress
import os
import re
import shutil
import signal
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path


def _state_root() -> Path:
    configured = os.environ.get("CORAL_ROBOT_RUNNER_STATE")
    if configured:
        return Path(configured)
    if os.geteuid() == 0:
        return Path("/run/coral-robot-runner")
    return Path(tempfile.gettempdir()) / f"coral-robot-runner-{os.geteuid()}"


# Slot locks live here; every runner on the machine (of this user) must agree on it.
STATE_ROOT = _state_root()
SLOTS = range(32)
# Marker put into every process the runner starts, so leftovers of a crashed run can be found.
PROCESS_MARKER = "CORAL_ROBOT_RUNNER_SLOT"


class NetworkError(RuntimeError):
    """An `ip` command failed; the message has the command and its stderr."""


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    result = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30, check=False)
    if check and result.returncode != 0:
        raise NetworkError(f"`ip {' '.join(args)}` exited with {result.returncode}: {result.stderr.strip()}")
    return result


def namespaces_supported() -> bool:
    """True when this process may create network namespaces (root and `ip` installed)."""
    return os.geteuid() == 0 and shutil.which("ip") is not None and Path("/proc/self/ns/net").exists()


def bridge_name(slot: int) -> str:
    return f"crr{slot}br"


def netns_name(slot: int, robot: str) -> str:
    return f"crr{slot}-{robot}"


def subnet(slot: int) -> ipaddress.IPv4Network:
    return ipaddress.IPv4Network(f"10.{208 + slot}.0.0/16")


def robot_address(slot: int, index: int) -> str:
    """Address of the robot with this index (0-based); .0.1 is the bridge."""
    return str(subnet(slot).network_address + 2 + index)


def gateway_address(slot: int) -> str:
    return str(subnet(slot).network_address + 1)


def claim_slot() -> tuple[int, int]:
    """Returns (slot, lock fd) of a slot no live runner holds; the lock dies with this process."""
    STATE_ROOT.mkdir(parents=True, exist_ok=True)
    for slot in SLOTS:
        fd = os.open(STATE_ROOT / f"slot-{slot}.lock", os.O_CREAT | os.O_RDWR, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            continue
        return slot, fd
    raise NetworkError(f"every robot-runner slot in {STATE_ROOT} is held by a running runner")


def marked_pids(slot: int) -> list[int]:
    marker = f"{PROCESS_MARKER}={slot}\0".encode()
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if marker in (entry / "environ").read_bytes():
                found.append(int(entry.name))
        except OSError:
            continue
    return found


def kill_leftovers(slot: int) -> list[int]:
    """SIGKILLs processes a previous runner of this slot started; returns their pids."""
    pids = marked_pids(slot)
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    return pids


def _kill_namespace_processes(netns: str) -> None:
    for pid in _ip("netns", "pids", netns, check=False).stdout.split():
        try:
            os.kill(int(pid), signal.SIGKILL)
        except (ProcessLookupError, ValueError):
            pass


def remove_slot_links(slot: int) -> None:
    """Deletes every namespace, veth and the bridge named for this slot (a no-op when none exist)."""
    if not namespaces_supported():
        return
    names = _ip("netns", "list", check=False).stdout.split("\n")
    for line in names:
        name = line.split(" ")[0]
        if name.startswith(f"crr{slot}-"):
            _kill_namespace_processes(name)
            _ip("netns", "delete", name, check=False)
    links = _ip("-o", "link", "show", check=False).stdout
    for match in re.finditer(rf"^\d+: (crr{slot}(?:h\d+|br))[@:]", links, flags=re.MULTILINE):
        _ip("link", "delete", match.group(1), check=False)


def cleanup_stale() -> list[int]:
    """Frees the slots of runners that died without cleaning up; returns those slots.

    A slot whose lock can be taken has no live owner, so whatever carries its name is stale.
    """
    freed = []
    if not STATE_ROOT.exists():
        return freed
    for slot in SLOTS:
        path = STATE_ROOT / f"slot-{slot}.lock"
        if not path.exists():
            continue
        fd = os.open(path, os.O_RDWR)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            continue
        try:
            if kill_leftovers(slot) or _slot_has_links(slot):
                freed.append(slot)
            remove_slot_links(slot)
        finally:
            os.close(fd)
    return freed


def _slot_has_links(slot: int) -> bool:
    return bool(slot_resources(slot))


def slot_resources(slot: int) -> list[str]:
    """Names of the namespaces and links of this slot that exist now."""
    if not namespaces_supported():
        return []
    found = [
        line.split(" ")[0]
        for line in _ip("netns", "list", check=False).stdout.splitlines()
        if line.startswith(f"crr{slot}-")
    ]
    links = _ip("-o", "link", "show", check=False).stdout
    found += re.findall(rf"^\d+: (crr{slot}(?:h\d+|br))[@:]", links, flags=re.MULTILINE)
    return found


@dataclass
class RobotLink:
    """One robot's place on the network."""

    robot: str
    index: int
    address: str
    netns: str | None
    host_veth: str | None
    up: bool = True


@dataclass
class Network:
    """The runner's bridge and robot namespaces; `isolated` False means the shared-host fallback."""

    slot: int
    isolated: bool
    links: dict[str, RobotLink] = field(default_factory=dict)
    _next_index: int = 0

    @classmethod
    def create(cls, slot: int, isolate: bool = True) -> Network:
        kill_leftovers(slot)
        isolated = isolate and namespaces_supported()
        network = cls(slot=slot, isolated=isolated)
        if isolated:
            remove_slot_links(slot)
            bridge = bridge_name(slot)
            _ip("link", "add", bridge, "type", "bridge", "mcast_snooping", "0")
            _ip("addr", "add", f"{gateway_address(slot)}/{subnet(slot).prefixlen}", "dev", bridge)
            _ip("link", "set", bridge, "up")
        return network

    @property
    def gateway(self) -> str:
        return gateway_address(self.slot) if self.isolated else "127.0.0.1"

    def add_robot(self, robot: str) -> RobotLink:
        if robot in self.links:
            return self.links[robot]
        index = self._next_index
        self._next_index += 1
        if not self.isolated:
            link = RobotLink(robot, index, "127.0.0.1", None, None)
            self.links[robot] = link
            return link
        ns = netns_name(self.slot, robot)
        host, peer = f"crr{self.slot}h{index}", f"crr{self.slot}p{index}"
        address = robot_address(self.slot, index)
        _ip("netns", "add", ns)
        _ip("link", "add", host, "type", "veth", "peer", "name", peer)
        _ip("link", "set", peer, "netns", ns)
        _ip("link", "set", host, "master", bridge_name(self.slot))
        _ip("link", "set", host, "up")
        _ip("-n", ns, "link", "set", peer, "name", "eth0")
        _ip("-n", ns, "addr", "add", f"{address}/{subnet(self.slot).prefixlen}", "dev", "eth0")
        _ip("-n", ns, "link", "set", "lo", "up")
        _ip("-n", ns, "link", "set", "eth0", "multicast", "on")
        _ip("-n", ns, "link", "set", "eth0", "up")
        _ip("-n", ns, "route", "add", "default", "via", gateway_address(self.slot))
        link = RobotLink(robot, index, address, ns, host)
        self.links[robot] = link
        return link

    def set_link(self, robot: str, up: bool) -> None:
        """Brings the robot's link up or down (namespaces only; the fallback just records it)."""
        link = self.links[robot]
        if link.host_veth is not None:
            _ip("link", "set", link.host_veth, "up" if up else "down")
        link.up = up

    def exec_prefix(self, robot: str) -> list[str]:
        """What to put before a command so it runs inside the robot's network."""
        link = self.links[robot]
        # Absolute, because containers' PATH (searched by Popen) need not include sbin.
        return [shutil.which("ip") or "/usr/sbin/ip", "netns", "exec", link.netns] if link.netns else []

    def remove_robot(self, robot: str) -> None:
        link = self.links.pop(robot, None)
        if link is None or link.netns is None:
            return
        _kill_namespace_processes(link.netns)
        _ip("netns", "delete", link.netns, check=False)
        if link.host_veth:
            _ip("link", "delete", link.host_veth, check=False)

    def close(self) -> None:
        for robot in list(self.links):
            self.remove_robot(robot)
        if self.isolated:
            _ip("link", "delete", bridge_name(self.slot), check=False)
