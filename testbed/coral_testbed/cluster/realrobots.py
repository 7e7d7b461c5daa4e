"""Real robots: an upstream kubelet and a containerd per robot, each robot in its own network and mount view.

`RealRobots` is the handle that `coral dev-cluster` (up --robots, robots stop|start|cut|restore),
`Cluster.robots` and the test fixtures use. What runs where is explained in docs/real-robots.md.
Robots are recorded in `<state dir>/robots/robots.json` after every step, so `remove_all` (called
by `controlplane.stop`) can tear down even what a crashed start left half made: processes,
mounts, network namespaces, links and cgroups.
"""

from __future__ import annotations

import functools
import http.client
import json
import os
import shutil
import socket
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from coral_testbed.cluster import (
    cgroups,
    components,
    mountview,
    nodeconfig,
    nodeimages,
    pki,
    processes,
    robotnet,
    robots,
)
from coral_testbed.cluster.uplink import entered_netns
from coral_testbed.waiting import WaitTimeout, wait_for

Progress = Callable[[str], None]
ROBOTS_DIR = "robots"
_STATE = "robots.json"
# Node processes started per robot, in start order (stopped in reverse).
PROCESSES = ("uplink", "containerd", "kubelet", "offline-agent")


class RobotError(RuntimeError):
    """A real robot could not be started, changed or removed; the message says which and why."""


def unsupported_reason(bin_dir: Path | None) -> str | None:
    """Why real robots cannot run on this machine, or None when they can."""
    if os.geteuid() != 0:
        return "real robots need root (network namespaces, mounts, cgroups)"
    if not robotnet.namespaces_supported():
        return "real robots need the `ip` command (iproute2) and network namespaces"
    for tool in ("containerd", "runc", "ctr", "nsenter", "unshare"):
        if shutil.which(tool) is None:
            return f"real robots need `{tool}`; install it with `sudo bash hack/setup-node-runtime.sh`"
    if not Path(nodeconfig.CNI_BIN_DIR, "bridge").exists():
        return f"real robots need the CNI plugins in {nodeconfig.CNI_BIN_DIR} (containernetworking-plugins)"
    for binary in ("kubelet", "crictl"):
        if bin_dir is None or not os.access(bin_dir / binary, os.X_OK):
            return f"{binary} is not built yet; run `make control-plane`"
    if not cgroups.hierarchies():
        return "no cgroup hierarchy is mounted"
    return None


class RealRobots:
    """The real robots of one local cluster (state folder), started against its API server.

    Args:
        state_dir: the control plane's state folder (robots live in `<state_dir>/robots/`).
        api: a client for the cluster, to wait on Nodes and delete them.
        api_port: the API server's port on 127.0.0.1.
        pki_dir: the control plane's certificates (signs each kubelet's client certificate).
        bin_dir: the pinned binaries (kubelet, crictl).
        die_with_parent: stop the node processes when this process dies (test sessions).
    """

    def __init__(
        self,
        state_dir: Path,
        api: k8s.ApiClient,
        api_port: int,
        pki_dir: Path,
        bin_dir: Path,
        die_with_parent: bool = False,
    ) -> None:
        self.state_dir = state_dir.resolve()
        self.api = api
        self.api_port = api_port
        self.pki = pki.Pki(pki_dir)
        self.bin_dir = bin_dir
        self.die_with_parent = die_with_parent

    # ---- recorded state ----------------------------------------------------------------------

    @property
    def folder(self) -> Path:
        return self.state_dir / ROBOTS_DIR

    @property
    def logs_dir(self) -> Path:
        return self.state_dir / "logs"

    def _load(self) -> dict[str, Any]:
        path = self.folder / _STATE
        if not path.exists():
            return {"slot": None, "robots": {}}
        try:
            return json.loads(path.read_text())
        except ValueError as error:
            raise RobotError(f"{path}: unreadable robot state ({error})") from error

    def _save(self, data: dict[str, Any]) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        path = self.folder / _STATE
        path.with_suffix(".tmp").write_text(json.dumps(data, indent=2))
        path.with_suffix(".tmp").replace(path)

    def names(self) -> list[str]:
        return list(self._load()["robots"])

    def layout(self, name: str) -> nodeconfig.RobotLayout:
        entry = self._load()["robots"].get(name)
        if entry is None:
            raise RobotError(f"{name} is not a real robot of {self.state_dir} (real robots: {self.names()})")
        return nodeconfig.RobotLayout.from_json(entry["layout"])

    def _recorded(self, name: str, process: str) -> processes.Recorded | None:
        entry = self._load()["robots"].get(name, {}).get("processes", {}).get(process)
        return processes.Recorded.from_json(entry) if entry else None

    def _record(self, name: str, process: str, recorded: processes.Recorded) -> None:
        data = self._load()
        data["robots"][name].setdefault("processes", {})[process] = recorded.to_json()
        self._save(data)

    # ---- starting ------------------------------------------------------------------------------

    def add(
        self,
        names: list[str],
        labels: dict[str, str] | None = None,
        progress: Progress = lambda _: None,
        timeout: float = 180,
        robot: bool = True,
    ) -> None:
        """Starts real robots and waits until their Nodes are Ready.

        With `robot=False` the nodes are plain cluster nodes (for the operator and other
        infrastructure): the same kubelet and containerd, but without the robot label, so no
        CoralSystem ever selects them; `labels` are still set.

        Raises:
            RobotError: the machine cannot host them, a name is taken, or a robot failed to start
                (the message has the failing process's log tail); every robot of the call is then
                torn down again.
        """
        reason = unsupported_reason(self.bin_dir)
        if reason:
            raise RobotError(reason)
        for name in names:
            robots.validate_robot_name(name)
        data = self._load()
        taken = [name for name in names if name in data["robots"]]
        if taken:
            raise RobotError(f"real robots {taken} exist already in {self.state_dir}")
        if data["slot"] is None:
            data["slot"] = robotnet.claim_slot()
            self._save(data)
        mountview.ensure_private_folder(self.folder / ".ns")
        registry = nodeconfig.registry_address()
        used = {entry["layout"]["index"] for entry in data["robots"].values()}
        try:
            for name in names:
                index = min(set(range(len(used) + 1)) - used)
                used.add(index)
                layout = nodeconfig.RobotLayout(
                    name=name,
                    slot=data["slot"],
                    index=index,
                    dir=self.folder / name,
                    bin_dir=self.bin_dir,
                    api_port=self.api_port,
                    registry=registry,
                    ca_cert=self.pki.ca_cert,
                )
                kind = "real robot" if robot else "real node"
                progress(f"Starting {kind} {name} at {layout.link.address}")
                # The kubelet registers only the robot label: NodeRestriction refuses kubelets some
                # label keys, so the others are the administrator's to set, below.
                self._start_robot(layout, {robots.ROBOT_LABEL: name} if robot else {})
            self.wait_ready(names, timeout=timeout)
            if labels:
                self._label(names, labels)
        except BaseException:
            for name in names:
                if name in self._load()["robots"]:
                    self._teardown(name)
            raise

    def _label(self, names: list[str], labels: dict[str, str]) -> None:
        core = k8s.CoreV1Api(self.api)
        wanted = {key: value for key, value in labels.items() if key != robots.ROBOT_LABEL}
        for name in names:
            try:
                core.patch_node(name, {"metadata": {"labels": wanted}})
            except ApiException as error:
                raise RobotError(
                    f"labels {wanted} refused for {name}: {error.status} {error.body}"
                ) from error

    def _start_robot(self, layout: nodeconfig.RobotLayout, labels: dict[str, str]) -> None:
        data = self._load()
        data["robots"][layout.name] = {"layout": layout.to_json(), "labels": labels, "processes": {}}
        self._save(data)
        robotnet.add_robot(layout.link)
        robotnet.route_api_service(layout.link, components.KUBERNETES_SERVICE_IP, layout.api_port)
        cgroups.create(layout.runtime_cgroup)
        mountview.create(layout.ns_file, layout.root, layout.name)
        cert, key = pki.sign_node_client(self.pki, layout.name)
        nodeconfig.write_files(layout, cert, key)
        self._start_uplink(layout)
        containerd = self._spawn(
            layout, "containerd", nodeconfig.build_containerd(layout), in_runtime_cgroup=True
        )
        containerd_socket = mountview.host_path(layout.root, nodeconfig.CONTAINERD_SOCKET)
        self._await(
            containerd, lambda: containerd_socket.exists() and self._ctr_ok(layout), "containerd to serve"
        )
        nodeimages.import_local(nodeconfig.build_ctr(layout), layout.image_cache)
        self._boot(layout, labels)

    def _boot(self, layout: nodeconfig.RobotLayout, labels: dict[str, str]) -> None:
        """What the robot's init system does once containerd serves: the offline agent's boot step,
        then the kubelet, then the agent beside it."""
        boot = subprocess.run(
            nodeconfig.build_offline_agent(layout, "boot"),
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )
        (self.logs_dir / f"{layout.name}.offline-boot.log").write_text(boot.stdout + boot.stderr)
        if boot.returncode != 0:
            raise RobotError(f"the offline agent's boot step on {layout.name} failed: {boot.stderr[-2000:]}")
        self._start_kubelet(layout, labels)
        self._spawn(
            layout, "offline-agent", nodeconfig.build_offline_agent(layout, "watch"), in_runtime_cgroup=True
        )

    def _spawn(
        self, layout: nodeconfig.RobotLayout, process: str, argv: list[str], in_runtime_cgroup: bool = False
    ) -> processes.Recorded:
        cgroup = layout.runtime_cgroup if in_runtime_cgroup else None
        recorded = processes.spawn(
            f"{layout.name}/{process}",
            argv,
            self.logs_dir / f"{layout.name}.{process}.log",
            die_with_parent=self.die_with_parent,
            before_exec=(lambda: cgroups.join(cgroup, os.getpid())) if cgroup else None,
        )
        self._record(layout.name, process, recorded)
        return recorded

    def _await(
        self, process: processes.Recorded, probe: Callable[[], bool], what: str, timeout: float = 60
    ) -> None:
        def up_or_dead() -> bool:
            if not processes.is_alive(process):
                raise RobotError(
                    f"{process.name} exited while waiting for {what}; last lines of {process.log}:\n"
                    f"{processes.log_tail(process.log)}"
                )
            return probe()

        try:
            wait_for(up_or_dead, timeout=timeout, interval=0.2, message=what)
        except WaitTimeout as error:
            raise RobotError(
                f"{error}; last lines of {process.log}:\n{processes.log_tail(process.log)}"
            ) from error

    def _start_uplink(self, layout: nodeconfig.RobotLayout) -> None:
        uplink = self._spawn(layout, "uplink", nodeconfig.build_uplink(layout))

        def listening() -> bool:
            with entered_netns(str(layout.link.netns_path)):
                try:
                    socket.create_connection(("127.0.0.1", layout.api_port), timeout=1).close()
                except OSError:
                    return False
            return True

        self._await(uplink, listening, f"the uplink of {layout.name} to listen")

    def _ctr_ok(self, layout: nodeconfig.RobotLayout) -> bool:
        result = subprocess.run(
            [*nodeconfig.build_ctr(layout), "version"], capture_output=True, timeout=30, check=False
        )
        return result.returncode == 0

    def _start_kubelet(self, layout: nodeconfig.RobotLayout, labels: dict[str, str]) -> None:
        kubelet = self._spawn(
            layout, "kubelet", nodeconfig.build_kubelet(layout, labels), in_runtime_cgroup=True
        )
        self._await(kubelet, lambda: kubelet_healthy(layout), f"the kubelet of {layout.name} to be healthy")

    def wait_ready(self, names: list[str], ready: str = "True", timeout: float = 180) -> None:
        """Waits until each robot's Node reports Ready=`ready` ("True", "False" or "Unknown")."""
        core = k8s.CoreV1Api(self.api)
        seen: dict[str, str | None] = {}

        def all_there() -> bool:
            for name in names:
                try:
                    seen[name] = robots.ready_status(core.read_node(name))
                except ApiException as error:
                    if error.status != 404:
                        raise
                    seen[name] = None
            return all(seen[name] == ready for name in names)

        wait_for(
            all_there,
            timeout=timeout,
            interval=0.5,
            message=lambda: f"robots to report Ready={ready} ({seen})",
        )

    # ---- faults ------------------------------------------------------------------------------

    def stop(self, name: str) -> None:
        """Stops the robot's kubelet; containers keep running, the Node turns NotReady after a grace."""
        self.layout(name)
        kubelet = self._recorded(name, "kubelet")
        if kubelet is not None:
            # The record stays, so `coral dev-cluster local status` shows the kubelet as stopped.
            processes.stop(kubelet)

    def start(self, name: str, wait: bool = True) -> None:
        """Starts the robot's kubelet again (a no-op when it runs) and waits until the Node is Ready."""
        layout = self.layout(name)
        kubelet = self._recorded(name, "kubelet")
        if kubelet is None or not processes.is_alive(kubelet):
            self._start_kubelet(layout, self._load()["robots"][name]["labels"])
        if wait:
            self.wait_ready([name])

    def power_cycle(self, name: str) -> None:
        """Power lost and back, the link left as it is: the kubelet, the agent, containerd, the shims
        and every container die (their cgroups are emptied with SIGKILL), then the robot boots:
        containerd, the offline agent's boot step, the kubelet, the agent. Returns once the kubelet
        is healthy (its Node's state is the API server's business)."""
        layout = self.layout(name)
        for process in ("offline-agent", "kubelet", "containerd"):
            recorded = self._recorded(name, process)
            if recorded is not None:
                processes.stop(recorded)
        cgroups.kill_all(layout.cgroup_root)
        containerd = self._spawn(
            layout, "containerd", nodeconfig.build_containerd(layout), in_runtime_cgroup=True
        )
        containerd_socket = mountview.host_path(layout.root, nodeconfig.CONTAINERD_SOCKET)
        self._await(
            containerd, lambda: containerd_socket.exists() and self._ctr_ok(layout), "containerd to serve"
        )
        self._boot(layout, self._load()["robots"][name]["labels"])

    def is_running(self, name: str) -> bool:
        kubelet = self._recorded(name, "kubelet")
        return kubelet is not None and processes.is_alive(kubelet)

    def cut_link(self, name: str) -> None:
        """Takes the robot off the network: its link goes down and its uplink to the host stops."""
        layout = self.layout(name)
        robotnet.set_link(layout.link, False)
        uplink = self._recorded(name, "uplink")
        if uplink is not None:
            processes.stop(uplink)

    def restore_link(self, name: str) -> None:
        layout = self.layout(name)
        robotnet.set_link(layout.link, True)
        uplink = self._recorded(name, "uplink")
        if uplink is None or not processes.is_alive(uplink):
            self._start_uplink(layout)

    def link_is_up(self, name: str) -> bool:
        return robotnet.link_is_up(self.layout(name).link)

    # ---- looking inside ----------------------------------------------------------------------

    def address(self, name: str) -> str:
        return self.layout(name).link.address

    def host_path(self, name: str, path: str) -> Path:
        """Where `path` of the robot (a hostPath volume, say) is on this machine."""
        return mountview.host_path(self.layout(name).root, path)

    def share_folder(self, server: str, clients: list[str], path: str, owner: int | None = None) -> Path:
        """`server`'s folder `path`, mounted at the same path on each of `clients`: one folder all
        of them see, as an NFS export of a site share would be. `owner` (a uid, also the gid)
        is given the folder, as a site administrator would for the components' user. Returns
        where the folder is on this machine.

        Raises:
            RobotError: a robot is unknown, or `path` is not a path robots own (mountview.PRIVATE).
        """
        exported = self.host_path(server, path)
        if not mountview.is_private(path):
            owned = ", ".join(mountview.PRIVATE)
            raise RobotError(f"{path} is not a path robots own ({owned}): cannot share it")
        exported.mkdir(parents=True, exist_ok=True)
        if owner is not None:
            os.chown(exported, owner, owner)
        for client in clients:
            layout = self.layout(client)
            try:
                mountview.bind_into(layout.ns_file, layout.root, exported, path)
            except mountview.MountError as error:
                raise RobotError(f"sharing {server}:{path} with {client}: {error}") from error
        return exported

    def enter(self, name: str) -> list[str]:
        """The command prefix that runs a command inside the robot's network and mount view."""
        return nodeconfig.enter_robot(self.layout(name))

    def cri(
        self, name: str, *args: str, check: bool = True, timeout: float = 60
    ) -> subprocess.CompletedProcess[str]:
        """Runs crictl against the robot's containerd, e.g. `cri(robot, "ps", "-q")`.

        Raises:
            RobotError: `check` is set and crictl failed (the message has its stderr).
        """
        argv = [*nodeconfig.build_cri(self.layout(name)), *args]
        result = subprocess.run(argv, capture_output=True, text=True, timeout=timeout, check=False)
        if check and result.returncode != 0:
            raise RobotError(
                f"`crictl {' '.join(args)}` on {name} exited with {result.returncode}: "
                f"{result.stderr.strip()}"
            )
        return result

    def ensure_image(self, name: str, image: str) -> None:
        """Makes `image` available on the robot (locally made images are imported; others are pulled)."""
        layout = self.layout(name)
        nodeimages.ensure_image(nodeconfig.build_ctr(layout), layout.image_cache, image)

    # ---- removing ----------------------------------------------------------------------------

    def remove(self, names: list[str]) -> None:
        """Tears the robots down and deletes their Nodes."""
        for name in names:
            self.layout(name)
            self._teardown(name)
            robots.delete_robots(self.api, [name])

    def remove_all(self, progress: Progress = lambda _: None) -> list[str]:
        """Tears down every robot, the bridge and the namespace folder (Nodes stay: the cluster may be going).

        Returns:
            what could not be removed; empty after a clean teardown.
        """
        return remove_all(self.state_dir, progress)

    def _teardown(self, name: str) -> None:
        teardown(self.state_dir, name)

    def leftovers(self, slot: int | None = None) -> list[str]:
        return leftovers(self.state_dir, slot)

    @property
    def slot(self) -> int | None:
        return self._load()["slot"]


def _load(state_dir: Path) -> dict[str, Any]:
    path = state_dir / ROBOTS_DIR / _STATE
    if not path.exists():
        return {"slot": None, "robots": {}}
    return json.loads(path.read_text())


def kubelet_healthy(layout: nodeconfig.RobotLayout) -> bool:
    """The kubelet's /healthz, asked inside the robot (it listens on the robot's own loopback)."""
    with entered_netns(str(layout.link.netns_path)):
        connection = http.client.HTTPConnection("127.0.0.1", nodeconfig.KUBELET_HEALTHZ_PORT, timeout=2)
        try:
            connection.request("GET", "/healthz")
            return connection.getresponse().read().strip() == b"ok"
        except (OSError, http.client.HTTPException):
            return False
        finally:
            connection.close()


def kubelet_probes(state_dir: Path) -> dict[str, Callable[[], bool]]:
    """A health probe per real robot's kubelet, keyed by its process name, for
    `coral dev-cluster local status`."""
    probes: dict[str, Callable[[], bool]] = {}
    for name, entry in _load(state_dir.resolve())["robots"].items():
        layout = nodeconfig.RobotLayout.from_json(entry["layout"])
        probes[f"{name}/kubelet"] = functools.partial(kubelet_healthy, layout)
    return probes


def node_processes(state_dir: Path) -> list[tuple[str, processes.Recorded]]:
    """(robot, process) for every recorded node process of the cluster in `state_dir`."""
    found = []
    for name, entry in _load(state_dir.resolve())["robots"].items():
        for process in PROCESSES:
            if process in entry.get("processes", {}):
                found.append((name, processes.Recorded.from_json(entry["processes"][process])))
    return found


def teardown(state_dir: Path, name: str) -> None:
    """Stops every process of one robot and removes its mounts, namespaces, link, cgroups and folder."""
    path = state_dir / ROBOTS_DIR / _STATE
    data = _load(state_dir)
    entry = data["robots"].get(name)
    if entry is None:
        return
    layout = nodeconfig.RobotLayout.from_json(entry["layout"])
    for process in reversed(PROCESSES):
        if process in entry.get("processes", {}):
            processes.stop(processes.Recorded.from_json(entry["processes"][process]))
    # containerd, its shims and every container live in the robot's cgroup subtree.
    cgroups.kill_all(layout.cgroup_root)
    mountview.remove(layout.ns_file)
    robotnet.remove_robot(layout.link)
    cgroups.remove(layout.cgroup_root)
    shutil.rmtree(layout.dir, ignore_errors=True)
    del data["robots"][name]
    path.with_suffix(".tmp").write_text(json.dumps(data, indent=2))
    path.with_suffix(".tmp").replace(path)


def remove_all(state_dir: Path, progress: Progress = lambda _: None) -> list[str]:
    """Tears down every real robot of the cluster in `state_dir`, then its bridge (a no-op without robots).

    Returns:
        what could not be removed (see `leftovers`); empty after a clean teardown.
    """
    state_dir = state_dir.resolve()
    data = _load(state_dir)
    for name in list(data["robots"]):
        progress(f"Removing real robot {name}")
        teardown(state_dir, name)
    if data["slot"] is not None:
        robotnet.remove_bridge(data["slot"])
    folder = state_dir / ROBOTS_DIR
    mountview.release_private_folder(folder / ".ns")
    if folder.exists():
        shutil.rmtree(folder / ".ns", ignore_errors=True)
        (folder / _STATE).unlink(missing_ok=True)
    return leftovers(state_dir, data["slot"])


def _processes_naming(marks: list[str]) -> list[str]:
    """Processes (other than this one) whose command line contains one of `marks`."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if any(mark in cmdline for mark in marks):
            found.append(f"process {entry.name}: {cmdline[:120]}")
    return found


def leftovers(state_dir: Path, slot: int | None) -> list[str]:
    """What real robots of this cluster left behind: node processes, mounts, namespaces, links, cgroups."""
    state_dir = state_dir.resolve()
    marks = [str(state_dir / ROBOTS_DIR)]
    if slot is not None:
        marks.append(f"/run/netns/{robotnet.netns_name(slot, '')}")
    found = _processes_naming(marks)
    found += [f"mount {point}" for point in mountview.mounts_under(state_dir / ROBOTS_DIR)]
    if slot is not None:
        found += [f"network {name}" for name in robotnet.slot_resources(slot)]
        for hierarchy in cgroups.hierarchies():
            found += [f"cgroup {p}" for p in hierarchy.glob(f"coral-{slot}-*")]
    return found


def robot_leftovers(layouts: list[nodeconfig.RobotLayout]) -> list[str]:
    """What these removed robots left behind (the cluster's other robots aside): their processes,
    mounts, namespace files, network namespaces and links, and cgroups."""
    marks = [str(layout.dir) for layout in layouts]
    marks += [f"/run/netns/{layout.link.netns}" for layout in layouts]
    found = _processes_naming(marks)
    for layout in layouts:
        found += [f"mount {point}" for point in mountview.mounts_under(layout.dir)]
        found += [
            f"namespace file {pinned}"
            for pinned in (layout.ns_file, mountview.uts_file(layout.ns_file))
            if pinned.exists()
        ]
        found += [f"network {name}" for name in robotnet.robot_resources(layout.link)]
        for hierarchy in cgroups.hierarchies():
            cgroup = hierarchy / layout.cgroup_root.lstrip("/")
            if cgroup.exists():
                found.append(f"cgroup {cgroup}")
    return found
