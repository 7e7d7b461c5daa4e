"""Starting, inspecting and stopping a local control plane whose state lives in one folder.

Called by `coral dev-cluster local up|down|status`, the demo and the pytest `cluster` fixture. `start`
launches etcd, kube-apiserver, kube-controller-manager, kube-scheduler and kwok as background
processes in their own process groups, records them in `<dir>/state.json` after every launch (so
`stop` can clean up even after a crash mid-start) and returns once the API serves and the
controllers work. Logs go to `<dir>/logs/`. Each `start` begins from an empty store.
"""

from __future__ import annotations

import json
import shutil
import socket
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tenacity

from coral_testbed.cluster import (
    binaries,
    components,
    health,
    kubeconfigs,
    pki,
    processes,
    robots,
)
from coral_testbed.waiting import WaitTimeout, wait_for

Progress = Callable[[str], None]

STATE_FILE = "state.json"


def default_state_dir() -> Path:
    return binaries.cache_root() / "dev-cluster"


class ControlPlaneError(RuntimeError):
    """A component failed to start or stop; the message names it and shows its log tail."""


class AlreadyRunning(ControlPlaneError):
    """The state folder already belongs to a running control plane."""


@dataclass
class State:
    """What `start` launched, as saved in state.json."""

    layout: components.Layout
    processes: list[processes.Recorded] = field(default_factory=list)
    started_at: float = 0.0

    @property
    def kubeconfig(self) -> Path:
        return self.layout.admin_kubeconfig

    def alive(self) -> list[processes.Recorded]:
        return [p for p in self.processes if processes.is_alive(p)]

    def save(self) -> None:
        data = {
            "layout": self.layout.to_json(),
            "processes": [p.to_json() for p in self.processes],
            "started_at": self.started_at,
        }
        path = self.layout.state_dir / STATE_FILE
        path.with_suffix(".tmp").write_text(json.dumps(data, indent=2))
        path.with_suffix(".tmp").replace(path)


def load_state(state_dir: Path) -> State | None:
    path = state_dir / STATE_FILE
    if not path.exists():
        return None
    try:
        data: dict[str, Any] = json.loads(path.read_text())
        return State(
            layout=components.Layout.from_json(data["layout"]),
            processes=[processes.Recorded.from_json(p) for p in data["processes"]],
            started_at=float(data.get("started_at", 0.0)),
        )
    except (ValueError, KeyError, TypeError) as error:
        raise ControlPlaneError(
            f"{path}: unreadable control-plane state ({error}); delete the folder"
        ) from error


def free_ports(count: int) -> list[int]:
    """Distinct ports free on 127.0.0.1 right now (held open together so none repeats)."""
    sockets = []
    try:
        for _ in range(count):
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            s.bind(("127.0.0.1", 0))
            sockets.append(s)
        return [s.getsockname()[1] for s in sockets]
    finally:
        for s in sockets:
            s.close()


def _prepare(state_dir: Path, bin_dir: Path) -> components.Layout:
    layout = components.Layout(state_dir, bin_dir, components.Ports(*free_ports(6)))
    for stale in ("etcd", "pki", "logs", "controller-manager-certs", "scheduler-certs"):
        shutil.rmtree(state_dir / stale, ignore_errors=True)
    state_dir.mkdir(parents=True, exist_ok=True)
    layout.logs_dir.mkdir()
    keys = pki.create_pki(layout.pki.dir)
    for identity, (common_name, _) in pki.CLIENTS.items():
        kubeconfigs.write_kubeconfig(
            layout.kubeconfig_for(identity),
            kubeconfigs.build_kubeconfig(
                server=layout.server,
                ca_cert=keys.ca_cert,
                client_cert=keys.client_cert(identity),
                client_key=keys.client_key(identity),
                user=common_name,
            ),
        )
    layout.kwok_config.write_text(robots.kwok_stages())
    layout.audit_policy.write_text(components.AUDIT_POLICY)
    return layout


def _await(state: State, process: processes.Recorded, probe: Callable[[], bool], timeout: float) -> None:
    """Waits for `probe`, failing fast with the log tail if the component exits."""

    def up_or_dead() -> bool:
        if not processes.is_alive(process):
            tail = processes.log_tail(process.log)
            raise ControlPlaneError(
                f"{process.name} exited during start-up; last lines of {process.log}:\n{tail}"
            )
        return probe()

    try:
        wait_for(up_or_dead, timeout=timeout, interval=0.25, message=f"{process.name} to become healthy")
    except WaitTimeout as error:
        raise ControlPlaneError(
            f"{error}; last lines of {process.log}:\n{processes.log_tail(process.log)}"
        ) from error


def _launch(state: State, name: str, argv: list[str], die_with_parent: bool) -> processes.Recorded:
    process = processes.spawn(
        name, argv, state.layout.logs_dir / f"{name}.log", die_with_parent=die_with_parent
    )
    state.processes.append(process)
    state.save()
    return process


def start(
    state_dir: Path | None = None,
    bin_dir: Path | None = None,
    progress: Progress = lambda _: None,
    die_with_parent: bool = False,
    timeout: float = 180.0,
    extra_args: Mapping[str, Sequence[str]] | None = None,
    heartbeats: components.Heartbeats = components.DEV_HEARTBEATS,
) -> State:
    """Starts every component and returns once the API is ready and the controllers work.

    Args:
        state_dir: folder for certificates, kubeconfigs, etcd data, logs and state.json.
        bin_dir: the pinned binaries (default: the build cache).
        progress: receives one line per step, for humans watching.
        die_with_parent: have the kernel stop the components if this process dies (test sessions).
        timeout: seconds allowed per component (generous: busy 2-core machines are slow).
        extra_args: more flags per component name (e.g. {"kube-controller-manager": ["--kube-api-qps=100"]}),
            for benchmarks that need a differently tuned control plane.
        heartbeats: how often robots renew their Leases and how soon a silent one turns Unknown.

    Raises:
        AlreadyRunning: the folder's control plane is still running.
        ControlPlaneError: a component failed; everything started so far is stopped again.
    """
    state_dir = (state_dir or default_state_dir()).resolve()
    bin_dir = bin_dir or binaries.find_bin_dir()
    previous = load_state(state_dir)
    if previous is not None and previous.alive():
        raise AlreadyRunning(
            f"a control plane is already running from {state_dir} (kubeconfig {previous.kubeconfig})"
        )
    began = time.monotonic()
    # Ports are chosen free but not held: another process may take one before its component binds
    # it. Only that race is worth another attempt; tenacity makes them and re-raises the last error.
    retrying = tenacity.Retrying(
        retry=tenacity.retry_if_exception(
            lambda error: isinstance(error, ControlPlaneError) and "address already in use" in str(error)
        ),
        stop=tenacity.stop_after_attempt(_ATTEMPTS),
        before_sleep=lambda _state: progress("A port was taken meanwhile; starting again on other ports"),
        reraise=True,
    )
    state = retrying(
        _start_once, state_dir, bin_dir, progress, die_with_parent, timeout, extra_args or {}, heartbeats
    )
    progress(f"Control plane ready in {time.monotonic() - began:.1f} s; kubeconfig: {state.kubeconfig}")
    return state


_ATTEMPTS = 3


def _start_once(
    state_dir: Path,
    bin_dir: Path,
    progress: Progress,
    die_with_parent: bool,
    timeout: float,
    extra_args: Mapping[str, Sequence[str]],
    heartbeats: components.Heartbeats,
) -> State:
    progress(f"Preparing certificates and kubeconfigs in {state_dir}")
    layout = _prepare(state_dir, bin_dir)
    state = State(layout=layout, started_at=time.time())
    state.save()
    ports, keys = layout.ports, layout.pki

    def launch(name: str, argv: list[str]) -> processes.Recorded:
        return _launch(state, name, [*argv, *extra_args.get(name, ())], die_with_parent)

    try:
        progress(f"Starting etcd on 127.0.0.1:{ports.etcd_client}")
        etcd = launch("etcd", components.build_etcd(layout))
        _await(state, etcd, lambda: health.etcd_healthy(ports.etcd_client), timeout)

        progress(f"Starting kube-apiserver on {layout.server}")
        apiserver = launch("kube-apiserver", components.build_apiserver(layout))
        admin = (keys.ca_cert, keys.client_cert("admin"), keys.client_key("admin"))
        _await(state, apiserver, lambda: health.apiserver_ready(ports.apiserver, *admin), timeout)

        progress("Starting kube-controller-manager, kube-scheduler and kwok")
        manager = launch("kube-controller-manager", components.build_controller_manager(layout, heartbeats))
        scheduler = launch("kube-scheduler", components.build_scheduler(layout))
        kwok = launch("kwok", components.build_kwok(layout, heartbeats=heartbeats))
        _await(state, manager, lambda: health.component_healthy(ports.controller_manager), timeout)
        _await(state, scheduler, lambda: health.component_healthy(ports.scheduler), timeout)
        _await(state, kwok, lambda: health.kwok_healthy(ports.kwok), timeout)

        # Pods cannot be created in a namespace before its default ServiceAccount exists, and that
        # account is made by the controller manager: its appearance proves the controllers work.
        _await(state, manager, lambda: _default_service_account_exists(layout.admin_kubeconfig), timeout)
    except BaseException:
        stop(state_dir)
        raise
    return state


def start_kwok(
    state_dir: Path,
    kubeconfig: Path,
    bin_dir: Path | None = None,
    die_with_parent: bool = False,
    timeout: float = 120.0,
    extra_args: Sequence[str] = (),
) -> State:
    """Runs only kwok, against an existing cluster (e.g. kind), so it can host simulated robots too.
    `extra_args`: more kwok flags, as `start`'s for its kwok.

    `stop(state_dir)` stops it again, like a full control plane.
    """
    state_dir = state_dir.resolve()
    bin_dir = bin_dir or binaries.find_bin_dir(("kwok",))
    previous = load_state(state_dir)
    if previous is not None and previous.alive():
        raise AlreadyRunning(f"kwok is already running from {state_dir}")
    port = free_ports(1)[0]
    layout = components.Layout(state_dir, bin_dir, components.Ports(0, 0, 0, 0, 0, port))
    layout.logs_dir.mkdir(parents=True, exist_ok=True)
    layout.kwok_config.write_text(robots.kwok_stages())
    state = State(layout=layout, started_at=time.time())
    try:
        kwok = _launch(state, "kwok", components.build_kwok(layout, kubeconfig, extra_args), die_with_parent)
        _await(state, kwok, lambda: health.kwok_healthy(port), timeout)
    except BaseException:
        stop(state_dir)
        raise
    return state


def _default_service_account_exists(kubeconfig: Path) -> bool:
    from kubernetes import client as k8s
    from kubernetes import config as k8s_config
    from kubernetes.client.exceptions import ApiException

    with k8s_config.new_client_from_config(config_file=str(kubeconfig)) as api:
        try:
            k8s.CoreV1Api(api).read_namespaced_service_account("default", "default")
        except ApiException as error:
            if error.status == 404:
                return False
            raise
    return True


def stop(state_dir: Path | None = None, progress: Progress = lambda _: None) -> list[processes.Recorded]:
    """Stops every recorded process (newest first) and returns them; a no-op if nothing runs."""
    state_dir = (state_dir or default_state_dir()).resolve()
    state = load_state(state_dir)
    if state is None:
        return []
    for process in reversed(state.processes):
        if processes.is_alive(process):
            progress(f"Stopping {process.name} (pid {process.pid})")
        processes.stop(process)
    leftover = state.alive()
    if leftover:
        raise ControlPlaneError(f"still running after stop: {[(p.name, p.pid) for p in leftover]}")
    (state_dir / STATE_FILE).unlink(missing_ok=True)
    return state.processes


def status(state_dir: Path | None = None) -> dict[str, Any]:
    """Liveness and health of each recorded component, for `coral dev-cluster local status`."""
    state_dir = (state_dir or default_state_dir()).resolve()
    state = load_state(state_dir)
    if state is None:
        return {"state_dir": str(state_dir), "running": False, "components": []}
    ports, keys = state.layout.ports, state.layout.pki
    probes: dict[str, Callable[[], bool]] = {
        "etcd": lambda: health.etcd_healthy(ports.etcd_client),
        "kube-apiserver": lambda: health.apiserver_ready(
            ports.apiserver, keys.ca_cert, keys.client_cert("admin"), keys.client_key("admin")
        ),
        "kube-controller-manager": lambda: health.component_healthy(ports.controller_manager),
        "kube-scheduler": lambda: health.component_healthy(ports.scheduler),
        "kwok": lambda: health.kwok_healthy(ports.kwok),
    }
    rows = []
    for process in state.processes:
        alive = processes.is_alive(process)
        rows.append(
            {
                "name": process.name,
                "pid": process.pid,
                "alive": alive,
                "healthy": alive and probes.get(process.name, lambda: True)(),
                "log": str(process.log),
            }
        )
    return {
        "state_dir": str(state_dir),
        "running": any(row["alive"] for row in rows),
        "healthy": bool(rows) and all(row["healthy"] for row in rows),
        "kubeconfig": str(state.kubeconfig),
        "server": state.layout.server,
        "components": rows,
    }
