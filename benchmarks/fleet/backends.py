"""Where the fleet benchmark's robots live: a kind cluster with kwok robots, or the local control plane.

Both give the benchmark what it reads: a kubeconfig, the control-plane processes whose CPU it
counts (host pids: kind's components run in the node container but are processes of this host),
kwok with the benchmark's options, the API server's audit log in the benchmark's folder, and the
same flags for the controller manager and the scheduler.

- `kind` (default): `coral_testbed.kind` makes the cluster (one control-plane node, no worker)
  and runs kwok against its API server; the flags reach kubeadm as configuration patches and the
  audit folder is bound into the node at the same path. The benchmark talks to the API server at
  the node's address on the cluster's network, not through Docker's port forward, whose proxy
  process would carry every request and whose CPU no figure would show.
- `local`: the testbed's own control plane (etcd and the control-plane binaries as processes),
  for a host without root or a Docker engine, and to compare with the figures measured on it
  (docs/performance.md has both).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import yaml
from coral_testbed.cluster import controlplane
from coral_testbed.kind import clusters, engine, provisioning

KIND_NAME = "fleet-bench"
"""The kind cluster's default name (`--kind-name`: another, for runs side by side on one engine)."""
CONTROL_PLANE = ("etcd", "kube-apiserver", "kube-controller-manager", "kube-scheduler")
BACKENDS = ("kind", "local")
"""The first is the default."""


@dataclass(frozen=True)
class BenchCluster:
    kubeconfig: Path
    pids: Callable[[], dict[str, int]]
    """Control-plane process name -> host pid, read when called (a restarted component counts anew)."""
    stop: Callable[[], None]


def start(
    backend: str,
    work: Path,
    extra_args: Mapping[str, Sequence[str]],
    audit_folder: Path,
    kind_name: str = KIND_NAME,
) -> BenchCluster:
    """A fresh cluster of `backend` with `extra_args` per component (`kwok` included) and the API
    server's audit files under `audit_folder`; `kind_name` names a kind cluster."""
    if backend == "local":
        return _start_local(work, extra_args)
    return _start_kind(kind_name, work, extra_args, audit_folder)


def _start_local(work: Path, extra_args: Mapping[str, Sequence[str]]) -> BenchCluster:
    folder = work / "control-plane"
    state = controlplane.start(folder, die_with_parent=True, extra_args=extra_args)
    return BenchCluster(
        kubeconfig=state.kubeconfig,
        pids=lambda: {p.name: p.pid for p in state.processes},
        stop=lambda: controlplane.stop(folder),
    )


def _say(line: str) -> None:
    print(f"# {line}", flush=True)


def _start_kind(
    name: str, work: Path, extra_args: Mapping[str, Sequence[str]], audit_folder: Path
) -> BenchCluster:
    reason = provisioning.unsupported_reason()
    if reason is not None:
        raise RuntimeError(
            f"{reason}; `--cluster local` (`make bench-fleet CLUSTER=local`) runs on the testbed's own "
            "control plane"
        )
    ready = provisioning.ensure(_say)
    if clusters.load(name, ready.engine) is not None:
        _say(f"kind cluster {name} is left from an earlier run; deleting it first")
    clusters.delete(name, ready.engine, _say)

    def stop() -> None:
        clusters.delete(name, ready.engine, _say)
        if clusters.stop_engine_unless_used(ready.engine):
            _say("stopped the project's dockerd")

    try:
        running = clusters.create(
            name,
            {},
            ready.engine,
            ready.node_image,
            _say,
            control_plane_args={k: v for k, v in extra_args.items() if k in CONTROL_PLANE},
            apiserver_folders=(str(audit_folder.resolve()),),
        )
        node = f"{name}-control-plane"
        direct = _direct_kubeconfig(running, node, work / "kubeconfig")
        clusters.start_kwok(dataclasses.replace(running, kubeconfig=direct), extra_args.get("kwok", ()))
    except BaseException:
        stop()
        raise
    kwok = controlplane.load_state(clusters.kwok_dir(name))

    def pids() -> dict[str, int]:
        found = _node_pids(ready.engine, node)
        if kwok is not None:
            found.update({p.name: p.pid for p in kwok.processes})
        return found

    return BenchCluster(kubeconfig=direct, pids=pids, stop=stop)


def _direct_kubeconfig(running: clusters.Running, node: str, path: Path) -> Path:
    """A copy of the cluster's kubeconfig that reaches the API server at the node's own address."""
    inspected = json.loads(running.engine.docker("inspect", node).stdout)[0]
    address = inspected["NetworkSettings"]["Networks"][clusters.network_name(running.name)]["IPAddress"]
    config = yaml.safe_load(running.kubeconfig.read_text())
    for entry in config["clusters"]:
        # kubeadm signs the API server's certificate for the node's address too.
        entry["cluster"]["server"] = f"https://{address}:6443"
    path.write_text(yaml.safe_dump(config))
    return path


def _node_pids(node_engine: engine.Engine, node: str) -> dict[str, int]:
    """The control-plane components running in the node container `node`, by name, as host pids."""
    return control_plane_pids(node_engine.docker("top", node, "-eo", "pid,args").stdout)


def control_plane_pids(top: str) -> dict[str, int]:
    """The control-plane components in `docker top NODE -eo pid,args` output, by name. Pure."""
    found: dict[str, int] = {}
    for line in top.splitlines()[1:]:
        # docker pads the PID column with spaces.
        pid, command = line.split(maxsplit=2)[:2]
        name = Path(command).name
        if name in CONTROL_PLANE:
            found[name] = int(pid)
    return found
