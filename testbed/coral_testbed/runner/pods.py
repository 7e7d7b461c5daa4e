"""One pod on one simulated robot: its containers as local processes, probes, restarts and status.

`runner.robots` owns one `PodWorker` per pod bound to its robot and calls `step` on every pass of
its loop (also while the robot's link is cut: a robot keeps running what it runs). The worker
never talks to the API itself; it returns the status to report and is told when the pod is gone.
"""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import IO, Any

import yaml
from coral_operator.planning.pods import PLUGINS_OWNER

from coral_testbed.runner import podspec, podstatus, probes, volumes

Clock = Callable[[], datetime]


@dataclass
class Robot:
    """What a pod needs to know about the robot it runs on."""

    name: str
    root: Path
    address: str
    exec_prefix: list[str]
    base_env: dict[str, str]
    api_server: str
    entrypoints: Mapping[str, list[str]]


@dataclass
class Container:
    spec: dict[str, Any]
    argv: list[str] = field(default_factory=list)
    env: dict[str, str] = field(default_factory=dict)
    cwd: Path | None = None
    probe: probes.Probe | None = None
    process: subprocess.Popen[bytes] | None = None
    log: IO[bytes] | None = None
    started_at: datetime | None = None
    restart_count: int = 0
    next_start: float = 0.0
    current_terminated: dict[str, Any] | None = None
    last_terminated: dict[str, Any] | None = None
    done: bool = False

    @property
    def name(self) -> str:
        return str(self.spec["name"])


class PodWorker:
    """Supervises one pod; see the module docstring."""

    def __init__(
        self,
        pod: dict[str, Any],
        robot: Robot,
        lookup: podspec.Lookup,
        tokens: volumes.TokenSource,
        clock: Clock = lambda: datetime.now(UTC),
    ) -> None:
        self.uid = pod["metadata"].get("uid", "")
        self.pod = pod
        self.robot = robot
        self._lookup = lookup
        self._tokens = tokens
        self._clock = clock
        self.started = clock()
        self.conditions = podstatus.Conditions()
        self.containers = [Container(spec=c) for c in pod["spec"].get("containers") or []]
        self.restart_policy = pod["spec"].get("restartPolicy", "Always")
        self.prepared = False
        self.config_error: str | None = None
        self._retry_at = 0.0
        self.terminating_since: float | None = None
        self._grace = 30.0

    @property
    def key(self) -> str:
        meta = self.pod["metadata"]
        return f"{meta.get('namespace')}/{meta['name']}"

    def update(self, pod: dict[str, Any]) -> None:
        self.pod = pod

    def _prepare(self) -> None:
        # The operator's plugin-folder owner step hands a root-made host folder to the components'
        # user; the runner makes that folder itself and runs every process as its own user, so the
        # step has nothing to do here. Any other init container (PodPerRobot's sidecars) is refused.
        inits = [c for c in self.pod["spec"].get("initContainers") or [] if c.get("name") != PLUGINS_OWNER]
        if inits:
            raise podspec.ContainerConfigError("initContainers are not supported by the robot runner")
        made = volumes.materialise(self.pod, self.robot.root, self._lookup, self._tokens, self.robot.address)
        for container in self.containers:
            paths = volumes.mount_map(container.spec, made)
            env = podspec.container_env(self.pod, container.spec, self._lookup, self.robot.address)
            env = {k: paths.rewrite(v) for k, v in env.items()}
            account = paths.local(volumes.SERVICE_ACCOUNT_DIR)
            if account is not None and "KUBECONFIG" not in env:
                env["KUBECONFIG"] = str(self._write_kubeconfig(account))
            container.env = {
                **self.robot.base_env,
                "HOSTNAME": self.robot.name
                if self.pod["spec"].get("hostNetwork")
                else self.pod["metadata"]["name"],
                **env,
            }
            container.argv = podspec.container_argv(
                container.spec, container.env, paths, self.robot.entrypoints
            )
            workdir = container.spec.get("workingDir")
            container.cwd = paths.local(workdir) if workdir else None
            if container.cwd is None:
                container.cwd = volumes.pod_dir(self.robot.root, self.pod)
            probe_spec = container.spec.get("readinessProbe")
            if probe_spec:
                container.probe = probes.Probe.from_spec(probe_spec, paths, container.env, container.name)
        self.prepared = True

    def _write_kubeconfig(self, account: Path) -> Path:
        """A kubeconfig for the pod's own ServiceAccount token (the in-cluster loader cannot work here)."""
        target = volumes.pod_dir(self.robot.root, self.pod) / "kubeconfig"
        cluster: dict[str, str] = {"server": self.robot.api_server}
        if (account / "ca.crt").exists():
            cluster["certificate-authority"] = str(account / "ca.crt")
        namespace = self.pod["metadata"]["namespace"]
        config = {
            "apiVersion": "v1",
            "kind": "Config",
            "clusters": [{"name": "cluster", "cluster": cluster}],
            "users": [{"name": "pod", "user": {"tokenFile": str(account / "token")}}],
            "contexts": [
                {"name": "pod", "context": {"cluster": "cluster", "user": "pod", "namespace": namespace}}
            ],
            "current-context": "pod",
        }
        target.write_text(yaml.safe_dump(config, sort_keys=False))
        return target

    def step(self) -> None:
        """Advances the pod by one supervision pass: prepare, reap, restart, start, probe."""
        now = time.monotonic()
        if self.terminating_since is not None:
            self._reap_all()
            return
        if not self.prepared:
            if now < self._retry_at:
                return
            try:
                self._prepare()
                self.config_error = None
            except podspec.ContainerConfigError as error:
                self.config_error = str(error)
                self._retry_at = now + 2.0
                return
        for container in self.containers:
            self._reap(container)
            if container.process is None and not container.done and now >= container.next_start:
                self._start(container)
            if container.probe is not None and container.process is not None:
                container.probe.step(self.robot.exec_prefix, now)

    def _start(self, container: Container) -> None:
        log_dir = volumes.pod_dir(self.robot.root, self.pod) / "logs"
        log_dir.mkdir(parents=True, exist_ok=True)
        # Kept open while the process runs; closed when it is reaped.
        container.log = open(log_dir / f"{container.name}.log", "ab")
        try:
            container.process = subprocess.Popen(
                self.robot.exec_prefix + container.argv,
                env=container.env,
                cwd=container.cwd,
                stdin=subprocess.DEVNULL,
                stdout=container.log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        except OSError as error:
            container.log.write(f"robot runner: cannot start {container.argv}: {error}\n".encode())
            container.log.close()
            container.process = None
            self._record_exit(container, 127, pid=None)
            return
        container.started_at = self._clock()
        container.current_terminated = None
        if container.probe is not None:
            container.probe.reset(time.monotonic())

    def _reap(self, container: Container) -> None:
        if container.process is None:
            return
        code = container.process.poll()
        if code is None:
            return
        pid = container.process.pid
        container.process = None
        if container.log is not None:
            container.log.close()
        self._record_exit(container, podstatus.exit_code_of(code), pid)

    def _record_exit(self, container: Container, code: int, pid: int | None) -> None:
        terminated = podstatus.terminated_state(code, container.started_at, self._clock(), pid)
        restart = self.restart_policy == "Always" or (self.restart_policy == "OnFailure" and code != 0)
        if restart and self.terminating_since is None:
            container.last_terminated = terminated
            container.restart_count += 1
            # Shorter than the kubelet's 10 s..5 min so tests and demos see restarts quickly.
            container.next_start = time.monotonic() + min(20.0, 0.5 * 2 ** min(container.restart_count, 6))
            container.current_terminated = None
        else:
            container.current_terminated = terminated
            container.done = True

    def terminate(self, grace_seconds: float) -> None:
        """Starts stopping every container: SIGTERM now, SIGKILL after the grace period."""
        if self.terminating_since is None:
            self.terminating_since = time.monotonic()
            self._grace = grace_seconds
            for container in self.containers:
                container.done = True
                _signal(container.process, signal.SIGTERM)
        self._reap_all()

    def _reap_all(self) -> None:
        overdue = (
            self.terminating_since is not None and time.monotonic() - self.terminating_since > self._grace
        )
        for container in self.containers:
            if overdue:
                _signal(container.process, signal.SIGKILL)
            self._reap(container)
            if container.probe is not None:
                container.probe.cancel()

    @property
    def stopped(self) -> bool:
        return all(c.process is None for c in self.containers)

    def kill(self, timeout: float = 10.0) -> None:
        """Stops every process now (runner shutdown): SIGTERM, then SIGKILL after `timeout`."""
        self.terminate(timeout)
        deadline = time.monotonic() + timeout + 5
        while not self.stopped and time.monotonic() < deadline:
            self._reap_all()
            time.sleep(0.05)

    def status(self) -> dict[str, Any]:
        """The pod status to report now."""
        now = self._clock()
        statuses = [self._container_status(c) for c in self.containers]
        states = [s["state"] for s in statuses]
        phase = podstatus.evaluate_phase(states, self.prepared)
        all_ready = bool(statuses) and all(s["ready"] for s in statuses)
        terminal = phase in ("Succeeded", "Failed")
        self.conditions.set("PodReadyToStartContainers", not terminal, now)
        self.conditions.set("Initialized", True, now)
        self.conditions.set("ContainersReady", all_ready, now, None if all_ready else "ContainersNotReady")
        ready_reason = "PodCompleted" if terminal else (None if all_ready else "ContainersNotReady")
        self.conditions.set("Ready", all_ready, now, ready_reason)
        self.conditions.set("PodScheduled", True, now)
        return podstatus.build_status(
            phase=phase,
            host_ip=self.robot.address,
            start_time=self.started,
            conditions=self.conditions,
            container_statuses=statuses,
        )

    def _container_status(self, container: Container) -> dict[str, Any]:
        state: dict[str, Any]
        running = container.process is not None
        if running:
            assert container.started_at is not None
            state = {"running": {"startedAt": podstatus.timestamp(container.started_at)}}
        elif container.current_terminated is not None:
            state = {"terminated": container.current_terminated}
        elif self.config_error is not None:
            state = {"waiting": {"reason": "CreateContainerConfigError", "message": self.config_error}}
        elif container.restart_count > 0:
            state = {"waiting": {"reason": "CrashLoopBackOff", "message": "back-off restarting the process"}}
        else:
            state = {"waiting": {"reason": "ContainerCreating"}}
        ready = running and (container.probe.ready if container.probe is not None else True)
        status: dict[str, Any] = {
            "name": container.name,
            "image": container.spec.get("image", ""),
            "imageID": "",
            "ready": ready,
            "started": running,
            "restartCount": container.restart_count,
            "state": state,
            "lastState": {"terminated": container.last_terminated} if container.last_terminated else {},
        }
        if container.process is not None:
            status["containerID"] = f"{podstatus.RUNTIME}://{container.process.pid}"
        return status


def _signal(process: subprocess.Popen[bytes] | None, sig: int) -> None:
    if process is None or process.poll() is not None:
        return
    try:
        os.killpg(process.pid, sig)
    except ProcessLookupError:
        pass
