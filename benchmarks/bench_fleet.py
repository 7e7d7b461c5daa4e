"""Benchmark: one CoralSystem over 100, 500 and 1000 kwok robots against a DaemonSet (DESIGN section 8).

Run by `make bench-fleet` (part of `make bench`); `python benchmarks/bench_fleet.py 100` runs one
size; `--plot DIR` also draws the times against robot count into DIR/fleet.png. For each size, on
a fresh local control plane (etcd, kube-apiserver, controller manager, scheduler, kwok) with that
many kwok robots, in the same run:

1. DaemonSet: one pod with the same three containers per robot; time until every pod is Ready,
   then a rolling update (`maxUnavailable: 10%`) after one environment variable changes.
2. Coral: the operator as a subprocess, one CoralSystem over the robots (three component pods
   and one CoralInstance per robot); time until the system is Ready with every robot ready, then
   the same change rolled out with `spec.rollout.maxUnavailable: 10%`.

Fairness: both runs share the apiserver, etcd and kwok (16 pod-stage workers instead of its
default few, for both). Client-side rate limits are raised for the DaemonSet's side (controller
manager and scheduler at 500 QPS, burst 1000); the operator's Python client has no client-side
limiter. API requests come from the apiserver's audit log, by
client (DaemonSet controller plus the scheduler's bindings, versus the operator).

Prints BENCH lines (ratios beside their targets) and `#` lines with the raw figures and, for the
operator, its CPU time and the request kinds it spent most on (the profile behind a miss).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import plots
from coral_testbed.cluster import controlplane
from fleet import audit, coral, daemonset, robots
from kubernetes import client as k8s
from kubernetes import config as k8s_config

SIZES = (100, 500, 1000)
TARGET_READY, TARGET_UPDATE, TARGET_RSS_MB = 1.5, 2.0, 300.0
# A robot runs three pods and one CoralInstance where the DaemonSet runs one pod.
REQUESTS_ALLOWANCE = 3.0
ROOT = Path(__file__).resolve().parents[1]
CLIENT_LIMITS = ["--kube-api-qps=500", "--kube-api-burst=1000"]
# With a thousand kwok Nodes on a busy 2-core machine, kwok's lease renewals can fall more than the
# test control plane's 30 s grace period behind; the Node then turns Unknown, its pods are marked
# not ready for good (kwok does not report them ready again) and neither run could finish. The
# kubelet default grace period is 40-50 s; 300 s keeps the benchmark about rollouts, for both runs.
NODE_GRACE = ["--node-monitor-grace-period=300s"]
# kwok plays pod stages with a few workers by default and falls behind at thousands of pods.
# More workers, for both runs.
KWOK_CONFIG = """apiVersion: config.kwok.x-k8s.io/v1alpha1
kind: KwokConfiguration
options:
  podPlayStageParallelism: 16
  nodePlayStageParallelism: 8
  nodeLeaseParallelism: 16
"""


def bench(name: str, value: float, unit: str, op: str, target: float) -> None:
    ok = value <= target if op == "<=" else value >= target
    print(
        f"BENCH name={name} value={value:.3g} unit={unit} target={op}{target:g} "
        f"result={'ok' if ok else 'miss'}",
        flush=True,
    )


def note(text: str) -> None:
    print(f"# {text}", flush=True)


def run_size(count: int, work: Path) -> plots.FleetPoint:
    timeout = 300 + count * 1.2
    extra, audit_path = audit.audit_flags(work / "audit")
    kwok_config = work / "kwok-options.yaml"
    kwok_config.write_text(KWOK_CONFIG)
    state = controlplane.start(
        work / "control-plane",
        die_with_parent=True,
        extra_args={
            "kube-apiserver": extra,
            "kube-controller-manager": CLIENT_LIMITS + NODE_GRACE,
            "kube-scheduler": CLIENT_LIMITS,
            "kwok": [f"--config={kwok_config}"],
        },
    )
    log = audit.AuditLog(audit_path)
    operator = None
    try:
        api = k8s_config.new_client_from_config(config_file=str(state.kubeconfig))
        api.user_agent = "coral-bench"
        core = k8s.CoreV1Api(api)
        began = time.monotonic()
        robots.create_robots(api, robots.robot_names(count))
        robots.wait_robots_ready(api, count, timeout=timeout)
        note(f"{count} robots Ready in {time.monotonic() - began:.1f} s")
        for namespace in ("bench-daemonset", "bench-coral"):
            core.create_namespace({"metadata": {"name": namespace}})

        log.mark()
        cpu_mark = _cpu(state)
        ds = daemonset.run_daemonset(api, "bench-daemonset", count, timeout)
        note(f"daemonset n={count}: CPU seconds by process: {_cpu_since(state, cpu_mark)}")
        time.sleep(2)  # let the batched audit backend flush the run's last requests before counting
        ds_requests = log.count_since_mark(audit.classify)
        note(
            f"daemonset n={count}: ready {ds.ready_seconds:.1f} s, rolling update {ds.update_seconds:.1f} s, "
            f"requests {dict(ds_requests)}"
        )
        daemonset.delete_daemonset(api, "bench-daemonset", timeout)

        env = {**_env(state.kubeconfig)}
        subprocess_ok = _apply_crds(env)
        if not subprocess_ok:
            raise RuntimeError("kubectl apply -f crds/ failed")
        operator = coral.OperatorProcess(env, "bench-coral", work / f"operator-{count}.log")
        coral.wait_operator_serving(api, "bench-coral", operator, timeout=180)
        cpu_before = coral.cpu_seconds(operator.process.pid)
        log.mark()
        cpu_mark = _cpu(state)
        result = coral.run_coral(api, "bench-coral", count, operator, timeout)
        cpu = coral.cpu_seconds(operator.process.pid) - cpu_before
        note(f"coral n={count}: CPU seconds by process: {_cpu_since(state, cpu_mark)}, operator {cpu:.1f}")
        time.sleep(2)
        kinds = log.count_since_mark(
            lambda e: audit.request_kind(e) if audit.classify(e) == "operator" else None
        )
        op_requests = sum(kinds.values())
        note(
            f"coral n={count}: ready {result.ready_seconds:.1f} s, "
            f"rolling update {result.update_seconds:.1f} s, "
            f"operator CPU {cpu:.1f} s over {result.ready_seconds + result.update_seconds:.1f} s, "
            f"operator requests {op_requests}"
        )
        if result.stalled:
            note(
                f"coral n={count}: the {result.stalled} phase did not finish within {timeout:.0f} s; "
                "its figure below is that timeout (see the operator log and status.rollout)"
            )
        note("operator requests by kind: " + ", ".join(f"{k}={v}" for k, v in kinds.most_common(8)))

        bench(f"fleet_ready_ratio_{count}", result.ready_seconds / ds.ready_seconds, "x", "<=", TARGET_READY)
        bench(
            f"fleet_update_ratio_{count}", result.update_seconds / ds.update_seconds, "x", "<=", TARGET_UPDATE
        )
        bench(f"operator_peak_rss_{count}", operator.peak_mb, "MB", "<=", TARGET_RSS_MB)
        ds_per_robot = (ds_requests["daemonset"] + ds_requests["scheduler"]) / count
        bench(
            f"fleet_api_requests_per_robot_{count}",
            op_requests / count,
            "requests",
            "<=",
            round(REQUESTS_ALLOWANCE * ds_per_robot, 1),
        )
        return plots.FleetPoint(
            robots=count,
            coral_ready_s=result.ready_seconds,
            coral_update_s=result.update_seconds,
            daemonset_ready_s=ds.ready_seconds,
            daemonset_update_s=ds.update_seconds,
        )
    finally:
        if operator is not None:
            operator.stop()
        controlplane.stop(work / "control-plane")


def _cpu(state: controlplane.State) -> dict[str, float]:
    return {p.name: coral.cpu_seconds(p.pid) for p in state.processes}


def _cpu_since(state: controlplane.State, mark: dict[str, float]) -> str:
    """CPU each control-plane process spent since `mark`: where a 2-core machine's time went."""
    now = _cpu(state)
    return ", ".join(f"{name}={now[name] - mark.get(name, 0.0):.1f}" for name in sorted(now))


def _env(kubeconfig: Path) -> dict[str, str]:
    import os

    return {**os.environ, "KUBECONFIG": str(kubeconfig)}


def _apply_crds(env: dict[str, str]) -> bool:
    import subprocess

    from coral_testbed.cluster import binaries

    kubectl = binaries.find_kubectl(None)
    result = subprocess.run(
        [kubectl, "apply", "--server-side", "-f", str(ROOT / "crds")], env=env, capture_output=True, text=True
    )
    if result.returncode != 0:
        print(result.stderr, file=sys.stderr)
        return False
    subprocess.run(
        [kubectl, "wait", "--for=condition=Established", "--timeout=60s", "crd", "--all"],
        env=env,
        capture_output=True,
        text=True,
    )
    return True


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sizes", nargs="*", type=int, help=f"robot counts (default: {SIZES})")
    parser.add_argument("--plot", type=Path, metavar="DIR", help="also write fleet.png into DIR")
    args = parser.parse_args(argv)
    points = []
    with tempfile.TemporaryDirectory(prefix="bench-fleet-") as folder:
        for count in args.sizes or SIZES:
            points.append(run_size(count, Path(folder) / f"n{count}"))
    if args.plot is not None:
        note(f"plot: {plots.fleet_times(points, args.plot)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
