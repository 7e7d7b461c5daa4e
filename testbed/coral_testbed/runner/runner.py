"""`RobotRunner`: acts as the kubelet of simulated robots, running their pods as local processes.

Test and demo tooling (DESIGN section 7), used by `coral robot-runner` and by integration tests.
Starting a runner claims a network slot, builds the bridge and one network namespace per robot
(`runner.network`), opens the Kubernetes API inside each namespace (`runner.forwarder`), registers
or adopts each robot's Node and starts one `robots.RobotAgent` per robot. `stop` (also on exit of
the `with` block) stops every process, reports the robots NotReady, and removes every namespace,
link and the bridge. docs/robot-runner.md explains the whole design.
"""

from __future__ import annotations

import logging
import os
import sys
import tempfile
import uuid
from collections.abc import Mapping
from pathlib import Path
from types import TracebackType
from urllib.parse import urlparse

from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from coral_testbed.runner import forwarder, network, pods, robots

log = logging.getLogger(__name__)

# Node annotation asking the runner to cut ("down") or restore ("up") a robot's link.
LINK_ANNOTATION = "coral.dev/simulate-link"

# Inherited variables that describe the runner's own world, not a container's.
_PRIVATE_ENV_PREFIXES = ("ROS_", "RMW_", "CORAL_", "KUBE", "FASTRTPS_", "FASTDDS_", "CYCLONEDDS_")


def base_environment(runner_env: Mapping[str, str], slot: int) -> dict[str, str]:
    """What every container starts from, as an image's ENV would: this machine's tools and venv.

    The project's venv comes first on PATH so `python -m ...` commands run project modules.
    """
    env = {k: v for k, v in runner_env.items() if not k.startswith(_PRIVATE_ENV_PREFIXES)}
    venv_bin = str(Path(sys.executable).parent)
    env["PATH"] = venv_bin + os.pathsep + runner_env.get("PATH", "/usr/bin:/bin")
    env[network.PROCESS_MARKER] = str(slot)
    return env


class RobotRunner:
    """Runs the pods of `robots` (Node names) against the cluster reached through `api`.

    Args:
        api: a client of the cluster (its kubeconfig's server must be loopback for the
            namespaced robots to reach it through the forwarder).
        robots: robot (Node) names; Nodes are created when missing.
        root: folder for robot files (`<root>/<robot>/host/...`); a temporary one by default.
        isolate: give each robot its own network namespace when this machine allows it.
        adopt: take over robots kwok currently simulates (their Nodes are re-created).
        entrypoints: image name (without tag) -> argv used when a container has no command.
    """

    def __init__(
        self,
        api: k8s.ApiClient,
        robots: list[str],
        root: Path | None = None,
        isolate: bool = True,
        adopt: bool = False,
        entrypoints: Mapping[str, list[str]] | None = None,
        interval: float = 0.3,
    ) -> None:
        self.api = api
        self.robot_names = list(dict.fromkeys(robots))
        self.root = Path(root) if root else Path(tempfile.mkdtemp(prefix="coral-robot-runner-"))
        self.isolate = isolate
        self.adopt = adopt
        self.entrypoints = dict(entrypoints or {})
        self.interval = interval
        self.runner_id = f"{os.uname().nodename}-{os.getpid()}-{uuid.uuid4().hex[:6]}"
        self.agents: dict[str, robots.RobotAgent] = {}
        self.forwarders: dict[str, forwarder.Forwarder] = {}
        self.network: network.Network | None = None
        self._slot_fd: int | None = None

    def __enter__(self) -> RobotRunner:
        self.start()
        return self

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()

    @property
    def isolated(self) -> bool:
        """True when robots really have separate networks (so `cut_link` also cuts DDS)."""
        return self.network is not None and self.network.isolated

    def robot_dir(self, robot: str) -> Path:
        return self.root / robot

    def host_path(self, robot: str, path: str) -> Path:
        """Where a hostPath of `robot` lives on this machine."""
        return self.robot_dir(robot) / "host" / path.lstrip("/")

    def address(self, robot: str) -> str:
        assert self.network is not None
        return self.network.links[robot].address

    def start(self) -> None:
        network.cleanup_stale()
        slot, self._slot_fd = network.claim_slot()
        try:
            self.network = network.Network.create(slot, isolate=self.isolate)
            target = self._api_target()
            for name in self.robot_names:
                self._add(name, slot, target)
            for agent in self.agents.values():
                agent.start()
        except BaseException:
            self.stop(report=False)
            raise
        log.info(
            "Robot runner started %d robots in %s (%s)",
            len(self.agents),
            self.root,
            "network namespaces" if self.isolated else "shared host network",
        )

    def _api_target(self) -> tuple[str, int]:
        url = urlparse(self.api.configuration.host)
        return url.hostname or "127.0.0.1", url.port or (443 if url.scheme == "https" else 80)

    def _add(self, name: str, slot: int, target: tuple[str, int]) -> None:
        assert self.network is not None
        link = self.network.add_robot(name)
        if link.netns is not None:
            # Inside the namespace the API keeps the cluster's own address, so TLS names still match.
            fwd = forwarder.Forwarder(link.netns, ("127.0.0.1", target[1]), target)
        else:
            fwd = forwarder.Forwarder(None, ("127.0.0.1", 0), target)
        self.forwarders[name] = fwd
        host = "127.0.0.1" if target[0] in ("localhost", "::1") else target[0]
        server = f"https://{host}:{fwd.address[1]}"
        robot_root = self.robot_dir(name)
        robot_root.mkdir(parents=True, exist_ok=True)
        robot = pods.Robot(
            name=name,
            root=robot_root,
            address=link.address,
            exec_prefix=self.network.exec_prefix(name),
            base_env=base_environment(os.environ, slot),
            api_server=server,
            entrypoints=self.entrypoints,
        )
        agent = robots.RobotAgent(robot, self.api, self.runner_id, self.adopt, interval=self.interval)
        agent.register()
        self.agents[name] = agent

    def cut_link(self, robot: str) -> None:
        """Cuts the robot off: its packets are dropped and its kubelet stops reaching the API."""
        self._set_link(robot, up=False)

    def restore_link(self, robot: str) -> None:
        self._set_link(robot, up=True)

    def _set_link(self, robot: str, up: bool) -> None:
        if robot not in self.agents:
            raise KeyError(f"robot {robot!r} is not run by this runner (robots: {sorted(self.agents)})")
        assert self.network is not None
        self.network.set_link(robot, up)
        self.forwarders[robot].set_enabled(up)
        self.agents[robot].set_connected(up)
        log.info("Robot %s link %s", robot, "restored" if up else "cut")

    def apply_link_annotations(self) -> list[str]:
        """Cuts or restores links as the robots' Nodes ask (`coral.dev/simulate-link: down|up`).

        Lets demos and other processes cut a link with `kubectl annotate`; the annotation is read
        from the runner's side of the network, so a cut robot can still be restored. Returns the
        robots whose link changed.
        """
        changed = []
        core = k8s.CoreV1Api(self.api)
        for name, agent in self.agents.items():
            try:
                annotations = core.read_node(name).metadata.annotations or {}
            except ApiException as error:
                if error.status == 404:
                    continue
                raise
            wanted = annotations.get(LINK_ANNOTATION, "up").lower()
            if wanted not in ("up", "down"):
                log.warning("Node %s: %s=%r is neither up nor down", name, LINK_ANNOTATION, wanted)
                continue
            if (wanted == "up") != agent.connected:
                self._set_link(name, up=wanted == "up")
                changed.append(name)
        return changed

    def stop(self, report: bool = True, remove_nodes: bool = False) -> None:
        """Stops every process and removes every network resource; idempotent.

        Args:
            report: mark the robots' Nodes NotReady (reason RobotRunnerStopped).
            remove_nodes: delete the robots' Nodes too (tests do, to leave the cluster as found).
        """
        for agent in self.agents.values():
            agent.stop(report=report)
        for fwd in self.forwarders.values():
            fwd.close()
        self.forwarders.clear()
        if remove_nodes:
            core = k8s.CoreV1Api(self.api)
            for name in self.agents:
                try:
                    core.delete_node(name)
                except ApiException as error:
                    if error.status != 404:
                        raise
        self.agents.clear()
        if self.network is not None:
            self.network.close()
            self.network = None
        if self._slot_fd is not None:
            os.close(self._slot_fd)
            self._slot_fd = None
