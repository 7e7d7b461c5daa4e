"""Benchmark: what one CoralInstance write costs the API server, against a ConfigMap write.

Run by `make bench-writes` (part of `make bench`). The fleet benchmark is bound by the API
server's CPU, and most of the operator's writes per robot are CoralInstance writes; this one
isolates their price. On a fresh local control plane it runs the operator over a few kwok robots
to get a real CoralInstance (spec and status as the operator writes them), stops it, and then, in
alternating rounds of `WRITES` requests each, measures the API server's CPU seconds per request for:

- creating a CoralInstance with that spec, against creating a ConfigMap holding the same spec as
  text (the same bytes through a built-in type);
- a merge patch of the instance's status, against a merge patch of the ConfigMap.

Prints BENCH lines; the target of each CoralInstance figure is twice its ConfigMap reference.
"""

from __future__ import annotations

import copy
import json
import statistics
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from coral_testbed.cluster import controlplane
from coral_testbed.waiting import wait_for
from fleet import coral, robots
from kubernetes import client as k8s
from kubernetes import config as k8s_config

ROBOTS = 3
WRITES = 200
ROUNDS = 3
TARGET_RATIO = 2.0
NAMESPACE = "bench-writes"


def bench(name: str, value: float, unit: str, target: float) -> None:
    result = "ok" if value <= target else "miss"
    print(
        f"BENCH name={name} value={value:.3g} unit={unit} target=<={target:.3g} result={result}", flush=True
    )


def real_instance(api: k8s.ApiClient, state: controlplane.State, work: Path) -> dict[str, Any]:
    """A CoralInstance as the operator writes it, from the fleet example over a few robots."""
    custom = k8s.CustomObjectsApi(api)
    operator = coral.OperatorProcess(coral.kube_env(state.kubeconfig), "bench-coral", work / "operator.log")
    try:
        coral.wait_operator_serving(api, "bench-coral", operator, timeout=180)
        custom.create_namespaced_custom_object(
            coral.GROUP,
            coral.VERSION,
            "bench-coral",
            coral.PLURAL,
            coral.build_system("bench-coral", "1", "10%"),
        )
        wait_for(
            lambda: coral.system_settled(coral._system(custom, "bench-coral", coral.NAME), ROBOTS),
            timeout=180,
            message="the operator to deploy the example",
        )
        items = custom.list_namespaced_custom_object(
            coral.GROUP, coral.VERSION, "bench-coral", "coralinstances"
        )
        return items["items"][0]
    finally:
        operator.stop()


def main() -> int:
    with tempfile.TemporaryDirectory(prefix="bench-writes-") as folder:
        work = Path(folder)
        state = controlplane.start(work / "control-plane", die_with_parent=True)
        try:
            return measure(state, work)
        finally:
            controlplane.stop(work / "control-plane")


def measure(state: controlplane.State, work: Path) -> int:
    api = k8s_config.new_client_from_config(config_file=str(state.kubeconfig))
    core, custom = k8s.CoreV1Api(api), k8s.CustomObjectsApi(api)
    robots.create_robots(api, robots.robot_names(ROBOTS))
    robots.wait_robots_ready(api, ROBOTS, timeout=120)
    for namespace in ("bench-coral", NAMESPACE):
        core.create_namespace({"metadata": {"name": namespace}})
    if not coral.apply_crds(coral.kube_env(state.kubeconfig)):
        raise SystemExit("kubectl apply -f crds/ failed")
    instance = real_instance(api, state, work)
    status = instance.get("status") or {}
    print(f"# a CoralInstance of {len(json.dumps(instance))} bytes, its status {len(json.dumps(status))}")
    apiserver = next(p.pid for p in state.processes if "apiserver" in p.name)

    def per_request_ms(write: Callable[[int], object], offset: int) -> float:
        before = coral.cpu_seconds(apiserver)
        for index in range(WRITES):
            write(offset + index)
        return (coral.cpu_seconds(apiserver) - before) / WRITES * 1000

    def create_instance(index: int) -> object:
        body = {key: copy.deepcopy(instance[key]) for key in ("apiVersion", "kind", "spec")}
        body["metadata"] = {"name": f"instance-{index}", "namespace": NAMESPACE}
        return custom.create_namespaced_custom_object(
            coral.GROUP, coral.VERSION, NAMESPACE, "coralinstances", body
        )

    def patch_instance(index: int) -> object:
        changed = copy.deepcopy(status)
        changed.setdefault("tree", {})["tickCount"] = index
        return custom.patch_namespaced_custom_object_status(
            coral.GROUP, coral.VERSION, NAMESPACE, "coralinstances", f"instance-{index}", {"status": changed}
        )

    text = json.dumps(instance["spec"])

    def create_config_map(index: int) -> object:
        body = {"metadata": {"name": f"config-{index}"}, "data": {"spec": text}}
        return core.create_namespaced_config_map(NAMESPACE, body)

    def patch_config_map(index: int) -> object:
        return core.patch_namespaced_config_map(
            f"config-{index}", NAMESPACE, {"data": {"status": f"{index}"}}
        )

    figures: dict[str, list[float]] = {
        name: []
        for name in ("instance create", "instance status patch", "configmap create", "configmap patch")
    }
    for round_index in range(ROUNDS):
        offset = round_index * WRITES
        # Alternating which kind goes first, so a load trend favours neither.
        order = [
            ("instance", create_instance, patch_instance),
            ("configmap", create_config_map, patch_config_map),
        ]
        for kind, create, patch in order if round_index % 2 == 0 else reversed(order):
            figures[f"{kind} create"].append(per_request_ms(create, offset))
            patch_name = "instance status patch" if kind == "instance" else "configmap patch"
            figures[patch_name].append(per_request_ms(patch, offset))
    medians = {name: statistics.median(values) for name, values in figures.items()}
    for name, value in medians.items():
        rounds = ", ".join(f"{v:.2f}" for v in figures[name])
        print(f"# API server CPU per request, {name}: {value:.2f} ms (rounds: {rounds})")
    bench(
        "apiserver_cpu_per_instance_create",
        medians["instance create"],
        "ms",
        TARGET_RATIO * medians["configmap create"],
    )
    bench(
        "apiserver_cpu_per_instance_status_patch",
        medians["instance status patch"],
        "ms",
        TARGET_RATIO * medians["configmap patch"],
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
