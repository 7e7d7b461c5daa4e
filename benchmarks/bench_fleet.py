"""Benchmark: one CoralSystem over 100, 500 and 1000 kwok robots against DaemonSets (DESIGN section 8).

Run by `make bench-fleet` (part of `make bench`); `python benchmarks/bench_fleet.py 100` runs one
size (`make bench-fleet SIZES=100` likewise); `--plot DIR` also draws the times against robot
count into DIR/fleet.png, and `--logs DIR` keeps the operator's log of each size in DIR (its work
queue says every 10 s how many passes ran, how long they took and how late they started).

For each size, on a fresh cluster with that many kwok robots (`--cluster kind`, the default: a kind
cluster, kwok against its API server; `--cluster local`: the testbed's own control plane of etcd,
kube-apiserver, controller manager, scheduler and kwok; `fleet.backends`), in the same run,
pairs of runs, each Coral run next to its reference (a cluster that has already created and
deleted thousands of pods is slower than a fresh one, and that drift must not land in a ratio),
and each run once the control plane is quiet
(a thousand new robots keep it busy for 10 to 15 s after they are Ready, and a deleted run's
objects for a while after they are gone). At the largest size each pair is run `--pairs` times
(default 3), in ABBA order, and each ratio is the median pair's (every pair is printed too):
one run of the same work on this 2-core machine can take half again as long as the next, mostly
kwok's, and one pair would judge that noise. Before those pairs one three-DaemonSet run warms the
new control plane up and is not judged: the first run on it is slower whichever side it is. The
pairs:

1. Three DaemonSets, one per `PodPerComponent` pod the operator plans (three pods per robot; their
   containers, environment, probes, volumes and identity; `fleet.daemonset`): the same shape as
   Coral's default layout, and its reference. Time until every pod is Ready, then a rolling update
   (`maxUnavailable: 10%`) after one environment variable changes.
2. Coral: the operator as a subprocess, one CoralSystem over the robots (three component pods
   and one CoralInstance per robot); time until the system is Ready with every robot ready, then
   the same change rolled out with `spec.rollout.maxUnavailable: 10%`.
3. One DaemonSet whose pod is the `PodPerRobot` pod the operator plans: the floor, and the
   reference of `PodPerRobot`. The same two phases. The operator keeps running (it only sees
   Node events meanwhile; its CPU during the run is printed).
4. Coral with `layout: PodPerRobot`: the same system once the first is deleted, one pod (two
   native sidecars and the executor) and one CoralInstance per robot.
5. The cost of the operator's metrics: Coral `PodPerComponent` again, each run on a fresh operator
   process, with its metrics served and scraped every 5 s against metrics off, in ABBA pairs; the
   operator's CPU from its start to the run's deletion, as a ratio (target: under 1.05x), and the
   series one scrape holds.
6. With `--baseline CHECKOUT` (an earlier commit with its own .venv): this operator against that
   one, each with its own CRDs, the same `PodPerComponent` runs in ABBA pairs with every optional
   feature at its default; the ratios of the times, the operator's CPU and its writes.

For each run it prints the API server's CPU seconds and every client's requests by kind, and for
the Coral runs the operator's writes per robot by kind (a collection delete counts as one), for
the first deployment and for the update separately. After the last size it
prints the growth of each time from one size to the next, per robot (1.0 is linear).

Fairness: all runs share the apiserver, etcd and kwok (16 pod-stage workers instead of its
default few, for all). Client-side rate limits are raised for the DaemonSets' side (controller
manager and scheduler at 500 QPS, burst 1000); the operator's Python client has no client-side
limiter. API requests come from the apiserver's audit log, by client (DaemonSet controller plus
the scheduler's bindings, versus the operator).

Prints BENCH lines (figures beside their targets) and `#` lines with the raw figures and, for the
operator, its CPU time and the request kinds it spent most on (the profile behind a miss).
"""

from __future__ import annotations

import argparse
import socket
import statistics
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import plots
from fleet import audit, backends, coral, daemonset, robots, scraping
from kubernetes import client as k8s
from kubernetes import config as k8s_config

SIZES = (100, 500, 1000)
# The targets are judged at the largest size, on the median of this many pairs of runs.
PAIRS_AT_LARGEST = 3
# Against the three DaemonSets, the same shape as `PodPerComponent` (DESIGN section 8).
TARGET_READY, TARGET_UPDATE, TARGET_RSS_MB = 1.25, 1.5, 300.0
# One pod per robot, against the single DaemonSet with the same three containers.
TARGET_ROBOT_POD_READY, TARGET_ROBOT_POD_UPDATE = 1.2, 1.5
# Per phase: the first deployment, then the update.
TARGET_WRITES_PER_ROBOT = 8.0
# The API server's CPU for a Coral run against its reference's run: the update's allowance.
TARGET_APISERVER_CPU = 1.5
# The operator's CPU over a run with its metrics served and scraped, against metrics off.
TARGET_METRICS_CPU = 1.05
SCRAPE_INTERVAL_S = 5.0
# This checkout against an earlier one (`--baseline`), same runs, optional features at their
# defaults: no regression beyond a run's noise on a busy 2-core machine. Writes move a little with
# time too: a start that lasts longer gets another progress write.
TARGET_BASELINE_TIME, TARGET_BASELINE_CPU, TARGET_BASELINE_WRITES = 1.1, 1.1, 1.05
# Seconds per robot at one size over the size before: near linear. Judged for Coral's layouts.
TARGET_GROWTH = 1.25
# Each Coral layout, its reference run, how that reference is built, and its time targets.
PAIRINGS = (
    ("PodPerComponent", "daemonsets3", daemonset.per_component, TARGET_READY, TARGET_UPDATE),
    ("PodPerRobot", "daemonset", daemonset.single, TARGET_ROBOT_POD_READY, TARGET_ROBOT_POD_UPDATE),
)
CORAL_LAYOUTS = tuple(layout for layout, *_ in PAIRINGS)
WRITE_VERBS = ("create", "update", "patch", "delete", "deletecollection")
ROOT = Path(__file__).resolve().parents[1]
# Each run starts once the control plane is quiet (`_wait_quiet`). Idle with 1000 kwok robots it
# uses 0.6 to 1.0 of a core, by host (kwok's heartbeats and the API server answering them).
QUIET_CORES, QUIET_WINDOW_S, QUIET_TIMEOUT_S = 1.0, 5.0, 120.0
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


@dataclass(frozen=True)
class Options:
    """What every size's run shares, from the command line."""

    backend: str = backends.BACKENDS[0]
    logs: Path | None = None
    """Where the operators' logs are kept (default: the run's temporary folder)."""
    layouts: tuple[str, ...] = CORAL_LAYOUTS
    baseline: Path | None = None
    """A checkout of an earlier commit with its own .venv, measured against this one."""
    kind_name: str = backends.KIND_NAME


@dataclass
class SizeFigures:
    """The times of one size's runs, for the growth lines and the plot."""

    robots: int
    times: dict[str, float]


def run_size(count: int, work: Path, options: Options, pairs: int = 1, largest: bool = True) -> SizeFigures:
    """`largest`: the run's largest size, where the metrics' cost is judged (elsewhere printed)."""
    logs, layouts = options.logs, options.layouts
    timeout = 300 + count * 1.2
    extra, audit_path = audit.audit_flags(work / "audit")
    kwok_config = work / "kwok-options.yaml"
    kwok_config.write_text(KWOK_CONFIG)
    state = backends.start(
        options.backend,
        work,
        {
            "kube-apiserver": extra,
            "kube-controller-manager": CLIENT_LIMITS + NODE_GRACE,
            "kube-scheduler": CLIENT_LIMITS,
            "kwok": [f"--config={kwok_config}"],
        },
        audit_path.parent,
        options.kind_name,
    )
    log = audit.AuditLog(audit_path)
    operator = None
    times: dict[str, float] = {}
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
        daemonset.create_executor_account(api, "bench-daemonset")
        # Installed before any run, as on a real cluster: the garbage collector learns of new
        # resource types only at its periodic discovery (30 s); until then it retries, with backoff,
        # every object whose owner it cannot map, a cost no real cluster's rollout pays.
        if not coral.apply_crds(coral.kube_env(state.kubeconfig)):
            raise RuntimeError("kubectl apply -f crds/ failed")

        if pairs > 1:
            # The first run on a new control plane is slower whichever side it is (kwok spent 1.5 to
            # 3.7 times the CPU of later runs on the same pods), and the ABBA order would hand it to
            # the first pair's reference: it runs once before the pairs and is not judged.
            _reference_run(api, state, log, count, timeout, "warm-up", daemonset.per_component, None)
        cpu: dict[str, float] = {}
        for layout, reference, build, ready_target, update_target in PAIRINGS:
            if layout not in layouts:
                continue
            ratios: list[tuple[float, float, float]] = []
            runs: dict[str, list[tuple[float, float]]] = {layout: [], reference: []}
            for index in range(pairs):
                # ABBA: a pair's two runs back to back (a cluster that has created and deleted
                # thousands of pods is slower than a fresh one, and that drift must not land in a
                # ratio), and every other pair in the other order, so a trend favours neither side.
                sides = ("reference", "coral") if index % 2 == 0 else ("coral", "reference")
                figures: dict[str, tuple[float, float, float]] = {}
                for side in sides:
                    if side == "reference":
                        figures[side] = _reference_run(
                            api, state, log, count, timeout, reference, build, operator
                        )
                    else:
                        operator = operator or _start_operator(
                            api, state, (logs or work) / f"operator-{count}.log"
                        )
                        result, apiserver, _ = _coral_run(
                            api, state, log, operator, count, timeout, layout, judge_writes=index == 0
                        )
                        figures[side] = (result.ready_seconds, result.update_seconds, apiserver)
                        coral.delete_system(api, "bench-coral", timeout)
                (ready, update, apiserver), (ref_ready, ref_update, ref_apiserver) = (
                    figures["coral"],
                    figures["reference"],
                )
                ratios.append((ready / ref_ready, update / ref_update, apiserver / ref_apiserver))
                runs[layout].append((ready, update))
                runs[reference].append((ref_ready, ref_update))
                cpu[layout], cpu[reference] = apiserver, ref_apiserver
                if pairs > 1:
                    note(
                        f"{layout} n={count} pair {index + 1}: ready {ratios[-1][0]:.2f}x, "
                        f"update {ratios[-1][1]:.2f}x, apiserver CPU {ratios[-1][2]:.2f}x its reference"
                    )
            tag = "fleet" if layout == "PodPerComponent" else "fleet_robot_pod"
            # The median pair: on a 2-core machine one run of the same work can take half again as
            # long as the next (docs/performance.md), and a single pair would judge that noise.
            for name, column, target in (
                (f"{tag}_ready_ratio_{count}", 0, ready_target),
                (f"{tag}_update_ratio_{count}", 1, update_target),
                (f"apiserver_cpu_ratio_{layout}_{count}", 2, TARGET_APISERVER_CPU),
            ):
                bench(name, statistics.median([ratio[column] for ratio in ratios]), "x", "<=", target)
            for run, measured in runs.items():
                times[f"{run}_ready"] = statistics.median([ready for ready, _ in measured])
                times[f"{run}_update"] = statistics.median([update for _, update in measured])
        note(
            f"apiserver CPU seconds n={count}: "
            + ", ".join(f"{run}={seconds:.1f}" for run, seconds in cpu.items())
        )
        if operator is not None:
            bench(f"operator_peak_rss_{count}", operator.peak_mb, "MB", "<=", TARGET_RSS_MB)
            # The metrics runs start operators of their own; two serving one namespace would race.
            operator.stop()
            operator = None
        runs = OperatorRuns(api, state, log, count, timeout, logs or work, pairs)
        if "PodPerComponent" in layouts:
            _metrics_cost(runs, judge=largest)
        if options.baseline is not None:
            _baseline_cost(runs, options.baseline)
        return SizeFigures(robots=count, times=times)
    finally:
        if operator is not None:
            operator.stop()
        state.stop()


def _reference_run(
    api: k8s.ApiClient,
    state: backends.BenchCluster,
    log: audit.AuditLog,
    count: int,
    timeout: float,
    run: str,
    build: Callable[[str, str, str], list[dict[str, Any]]],
    operator: coral.OperatorProcess | None,
) -> tuple[float, float, float]:
    """One DaemonSet reference run, with its figures printed: (ready s, update s, API server CPU s).
    `operator`: the operator if it runs already, whose CPU meanwhile (watching robots) is printed."""
    operator_before = coral.cpu_seconds(operator.process.pid) if operator is not None else 0.0
    _wait_quiet(state, run, count)
    log.mark()
    cpu_mark = _cpu(state)
    ds = daemonset.run_daemonsets(api, "bench-daemonset", count, timeout, build)
    if operator is not None:
        note(
            f"{run} n={count}: the operator, watching robots meanwhile, spent "
            f"{coral.cpu_seconds(operator.process.pid) - operator_before:.1f} CPU s"
        )
    apiserver = _apiserver_cpu(state, cpu_mark)
    note(f"{run} n={count}: CPU seconds by process: {_cpu_since(state, cpu_mark)}")
    time.sleep(2)  # let the batched audit backend flush the run's last requests before counting
    requests = log.count_since_mark(audit.classify)
    note(
        f"{run} n={count}: ready {ds.ready_seconds:.1f} s, rolling update {ds.update_seconds:.1f} s, "
        f"apiserver CPU {apiserver:.1f} s, requests {dict(requests)}"
    )
    everyone = log.count_since_mark(audit.client_and_kind)
    note(
        f"{run} n={count}: all requests by client: "
        + ", ".join(f"{k}={v}" for k, v in everyone.most_common(16))
    )
    daemonset.delete_daemonsets(api, "bench-daemonset", timeout)
    return ds.ready_seconds, ds.update_seconds, apiserver


def _start_operator(
    api: k8s.ApiClient, state: backends.BenchCluster, log_path: Path
) -> coral.OperatorProcess:
    operator = coral.OperatorProcess(coral.kube_env(state.kubeconfig), "bench-coral", log_path)
    coral.wait_operator_serving(api, "bench-coral", operator, timeout=180)
    return operator


def _coral_run(
    api: k8s.ApiClient,
    state: backends.BenchCluster,
    log: audit.AuditLog,
    operator: coral.OperatorProcess,
    count: int,
    timeout: float,
    layout: str,
    *,
    judge_writes: bool = True,
) -> tuple[coral.CoralResult, float, float]:
    """One Coral run in `layout`: its times, with its figures printed; returns the API server's CPU
    and the operator's writes per robot (deployment and update).
    `judge_writes`: print the writes per robot as BENCH lines (the first run of a layout's pairs)."""
    _wait_quiet(state, layout, count)
    cpu_before = coral.cpu_seconds(operator.process.pid)
    cpu_mark = _cpu(state)
    kinds: dict[str, Counter[str]] = {}
    everyone: dict[str, Counter[str]] = {}

    def count_phase(phase: str) -> None:
        time.sleep(2)  # let the batched audit backend flush the phase's last requests before counting
        kinds[phase] = log.count_since_mark(
            lambda e: audit.request_kind(e) if audit.classify(e) == "operator" else None
        )
        everyone[phase] = log.count_since_mark(audit.client_and_kind)
        log.mark()

    log.mark()
    result = coral.run_coral(
        api, "bench-coral", count, operator, timeout, layout, between=lambda: count_phase("deploy")
    )
    apiserver = _apiserver_cpu(state, cpu_mark)
    cpu = coral.cpu_seconds(operator.process.pid) - cpu_before
    count_phase("update")
    note(
        f"coral {layout} n={count}: CPU seconds by process: {_cpu_since(state, cpu_mark)}, operator {cpu:.1f}"
    )
    total = sum(kinds["deploy"].values()) + sum(kinds["update"].values())
    written = 0
    note(
        f"coral {layout} n={count}: ready {result.ready_seconds:.1f} s, "
        f"rolling update {result.update_seconds:.1f} s, "
        f"operator CPU {cpu:.1f} s over {result.ready_seconds + result.update_seconds:.1f} s, "
        f"apiserver CPU {apiserver:.1f} s, operator requests {total}"
    )
    if result.stalled:
        note(
            f"coral {layout} n={count}: the {result.stalled} phase did not finish within {timeout:.0f} s; "
            "its figure below is that timeout (see the operator log and status.rollout)"
        )
    for phase in ("deploy", "update"):
        counted = kinds.get(phase, Counter())
        note(
            f"operator requests by kind ({layout}, {phase}): "
            + ", ".join(f"{k}={v}" for k, v in counted.most_common(10))
        )
        writes = {kind: n for kind, n in counted.items() if kind.split(" ", 1)[0] in WRITE_VERBS}
        written += sum(writes.values())
        note(
            f"all requests by client ({layout}, {phase}): "
            + ", ".join(f"{k}={v}" for k, v in everyone.get(phase, Counter()).most_common(16))
        )
        note(
            f"operator writes per robot ({layout}, {phase}): "
            + ", ".join(f"{k}={v / count:.2f}" for k, v in sorted(writes.items(), key=lambda kv: -kv[1]))
        )
        if judge_writes:
            bench(
                f"operator_writes_per_robot_{layout}_{phase}_{count}",
                sum(writes.values()) / count,
                "writes",
                "<=",
                TARGET_WRITES_PER_ROBOT,
            )
    return result, apiserver, written / count


@dataclass(frozen=True)
class Variant:
    """One side of an A/B comparison of operators: what its operator process is started with."""

    metrics: bool = False
    """Serve the operator's metrics and scrape them every SCRAPE_INTERVAL_S."""
    checkout: Path | None = None
    """Run the operator (and apply the CRDs) of this checkout, with its own .venv."""


@dataclass(frozen=True)
class RunFigures:
    ready: float
    update: float
    cpu: float
    """The operator's CPU seconds from its start to the run's deletion."""
    writes: float
    """The operator's writes per robot, deployment and update."""


@dataclass(frozen=True)
class OperatorRuns:
    """What a size's A/B comparisons of operators run on."""

    api: k8s.ApiClient
    state: backends.BenchCluster
    log: audit.AuditLog
    count: int
    timeout: float
    folder: Path
    pairs: int

    def compare(self, label: str, variants: dict[str, Variant]) -> list[dict[str, RunFigures]]:
        """`Coral PodPerComponent` runs (start, deployment, update, deletion), each on a fresh operator
        process, one per variant in each pair, pairs in ABBA order (a trend favours neither side)."""
        figures: list[dict[str, RunFigures]] = []
        for index in range(self.pairs):
            sides = list(variants) if index % 2 == 0 else list(reversed(variants))
            figures.append({side: self._run(label, side, variants[side], index) for side in sides})
        return figures

    def _run(self, label: str, side: str, variant: Variant, index: int) -> RunFigures:
        env = coral.kube_env(self.state.kubeconfig)
        crds = (variant.checkout or ROOT) / "crds"
        # Each operator with its own CRDs, as it is released: an older one may refuse newer fields.
        if not coral.apply_crds(env, crds):
            raise RuntimeError(f"kubectl apply -f {crds} failed")
        address = f"127.0.0.1:{_free_port()}" if variant.metrics else None
        log_path = self.folder / f"operator-{label}-{side}-{self.count}-{index}.log"
        operator = coral.OperatorProcess(env, "bench-coral", log_path, address, variant.checkout)
        scraper = None
        try:
            coral.wait_operator_serving(self.api, "bench-coral", operator, timeout=180)
            if address is not None:
                scraper = scraping.Scraper(f"http://{address}/metrics", SCRAPE_INTERVAL_S)
            origin = f" from {variant.checkout}" if variant.checkout else ""
            note(
                f"{label} {side} n={self.count}: the next run's operator{origin} "
                f"serves {address or 'no metrics'}"
            )
            result, _, writes = _coral_run(
                self.api,
                self.state,
                self.log,
                operator,
                self.count,
                self.timeout,
                "PodPerComponent",
                judge_writes=False,
            )
            coral.delete_system(self.api, "bench-coral", self.timeout)
            cpu = coral.cpu_seconds(operator.process.pid)
        finally:
            if scraper is not None:
                scraper.stop()
                note(
                    f"metrics on n={self.count}: {scraper.series} series in one scrape, "
                    f"{scraper.scrapes} scrapes, {scraper.failures} failed"
                )
            operator.stop()
        return RunFigures(result.ready_seconds, result.update_seconds, cpu, writes)


def _metrics_cost(runs: OperatorRuns, *, judge: bool) -> None:
    """The operator's CPU over one `PodPerComponent` run, its metrics served and scraped every
    SCRAPE_INTERVAL_S, against the same run with metrics off, judged on the median pair's ratio.
    Also prints how many series one scrape holds, which does not grow with the robots. Judged
    (`judge`) at the largest size only: a smaller fleet's run costs the operator a few CPU seconds,
    within which one pair's noise is more than the metrics' cost."""
    count = runs.count
    ratios: list[float] = []
    for index, pair in enumerate(runs.compare("metrics", {"off": Variant(), "on": Variant(metrics=True)})):
        ratios.append(pair["on"].cpu / pair["off"].cpu)
        note(
            f"metrics n={count} pair {index + 1}: operator CPU {pair['on'].cpu:.1f} s with metrics, "
            f"{pair['off'].cpu:.1f} s without ({ratios[-1]:.3f}x)"
        )
    ratio = statistics.median(ratios)
    if judge:
        bench(f"operator_metrics_cpu_ratio_{count}", ratio, "x", "<=", TARGET_METRICS_CPU)
    else:
        note(f"operator_metrics_cpu_ratio_{count} (not judged below the largest size): {ratio:.3g}x")


def _baseline_cost(runs: OperatorRuns, baseline: Path) -> None:
    """This checkout's operator against `baseline`'s (an earlier commit with its own .venv) on the
    same runs, every optional feature at its default: the times, the operator's CPU and its writes,
    as ratios of the median pair (above 1: this checkout is slower or busier)."""
    count = runs.count
    pairs = runs.compare("baseline", {"baseline": Variant(checkout=baseline), "current": Variant()})
    for index, pair in enumerate(pairs):
        now, before = pair["current"], pair["baseline"]
        note(
            f"baseline n={count} pair {index + 1}: ready {now.ready:.1f} s against {before.ready:.1f} s, "
            f"update {now.update:.1f} s against {before.update:.1f} s, operator CPU {now.cpu:.1f} s "
            f"against {before.cpu:.1f} s, writes per robot {now.writes:.2f} against {before.writes:.2f}"
        )
    for name, field_name, target in (
        ("ready", "ready", TARGET_BASELINE_TIME),
        ("update", "update", TARGET_BASELINE_TIME),
        ("operator_cpu", "cpu", TARGET_BASELINE_CPU),
        ("operator_writes", "writes", TARGET_BASELINE_WRITES),
    ):
        ratios = [getattr(p["current"], field_name) / getattr(p["baseline"], field_name) for p in pairs]
        bench(f"baseline_{name}_ratio_{count}", statistics.median(ratios), "x", "<=", target)


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def report_growth(figures: list[SizeFigures]) -> None:
    """Seconds per robot at each size over the size before (1.0: linear; above: worse than linear).
    Coral's layouts are judged; the references' growth is printed beside them as a note, since it
    is the control plane's own (the DaemonSet controller's work grows faster than linearly)."""
    ordered = sorted(figures, key=lambda f: f.robots)
    for before, after in zip(ordered, ordered[1:], strict=False):
        for series in sorted(after.times):
            if series not in before.times or not before.times[series]:
                continue
            growth = (after.times[series] / after.robots) / (before.times[series] / before.robots)
            name = f"fleet_growth_{series}_{before.robots}_{after.robots}"
            if series.startswith(CORAL_LAYOUTS):
                bench(name, growth, "x", "<=", TARGET_GROWTH)
            else:
                note(f"{name} (reference): {growth:.3g}x")


def _wait_quiet(state: backends.BenchCluster, run: str, count: int) -> None:
    """Wait until the control plane is as quiet as it gets with this many robots (its processes
    below QUIET_CORES over a QUIET_WINDOW_S window), at most QUIET_TIMEOUT_S. A thousand new
    robots keep it busy on both cores for 10 to 15 s after they are Ready, and a deleted run's
    objects for a while after they are gone; a run started then would carry that work too."""
    began = time.monotonic()
    while True:
        mark = _cpu(state)
        time.sleep(QUIET_WINDOW_S)
        cores = sum(_cpu_delta(state, mark).values()) / QUIET_WINDOW_S
        waited = time.monotonic() - began
        if cores < QUIET_CORES or waited > QUIET_TIMEOUT_S:
            note(f"{run} n={count}: started after {waited:.0f} s, the control plane at {cores:.2f} cores")
            return


def _apiserver_cpu(state: backends.BenchCluster, mark: dict[str, float]) -> float:
    return sum(seconds for name, seconds in _cpu_delta(state, mark).items() if "apiserver" in name)


def _cpu(state: backends.BenchCluster) -> dict[str, float]:
    return {name: coral.cpu_seconds(pid) for name, pid in state.pids().items()}


def _cpu_delta(state: backends.BenchCluster, mark: dict[str, float]) -> dict[str, float]:
    """CPU seconds each control-plane process spent since `mark` (a `_cpu` reading)."""
    now = _cpu(state)
    return {name: now[name] - mark.get(name, 0.0) for name in now}


def _cpu_since(state: backends.BenchCluster, mark: dict[str, float]) -> str:
    """CPU each control-plane process spent since `mark`: where a 2-core machine's time went."""
    return ", ".join(f"{name}={seconds:.1f}" for name, seconds in sorted(_cpu_delta(state, mark).items()))


def parse_arguments(argv: list[str]) -> tuple[argparse.Namespace, Options]:
    """The command line, and the options every size's run shares. Pure but for the `--baseline` check."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sizes", nargs="*", type=int, help=f"robot counts (default: {SIZES})")
    parser.add_argument("--plot", type=Path, metavar="DIR", help="also write fleet.png into DIR")
    parser.add_argument("--logs", type=Path, metavar="DIR", help="keep the operator logs in DIR")
    parser.add_argument(
        "--pairs",
        type=int,
        default=PAIRS_AT_LARGEST,
        help=f"pairs of runs at the largest size (default {PAIRS_AT_LARGEST}; one at the others)",
    )
    parser.add_argument(
        "--layout",
        action="append",
        choices=CORAL_LAYOUTS,
        help="measure only this layout against its reference (repeatable; default: every layout)",
    )
    parser.add_argument(
        "--cluster",
        choices=backends.BACKENDS,
        default=backends.BACKENDS[0],
        help="kind (default): a kind cluster with kwok robots; local: the testbed's own control plane",
    )
    parser.add_argument(
        "--kind-name",
        default=backends.KIND_NAME,
        help=f"the kind cluster's name with --cluster kind (default {backends.KIND_NAME})",
    )
    parser.add_argument(
        "--baseline",
        type=Path,
        metavar="CHECKOUT",
        help="also measure the operator of CHECKOUT (an earlier commit with its own .venv) against this one",
    )
    args = parser.parse_args(argv)
    if args.baseline is not None and not (args.baseline / ".venv" / "bin" / "python").exists():
        parser.error(f"{args.baseline} has no .venv/bin/python (run `make venv` there)")
    options = Options(
        args.cluster, args.logs, tuple(args.layout or CORAL_LAYOUTS), args.baseline, args.kind_name
    )
    return args, options


def main(argv: list[str]) -> int:
    args, options = parse_arguments(argv)
    sizes = args.sizes or SIZES
    figures = []
    with tempfile.TemporaryDirectory(prefix="bench-fleet-") as folder:
        for count in sizes:
            if args.logs is not None:
                args.logs.mkdir(parents=True, exist_ok=True)
            pairs = max(1, args.pairs) if count == max(sizes) else 1
            work = Path(folder) / f"n{count}"
            figures.append(run_size(count, work, options, pairs, largest=count == max(sizes)))
    report_growth(figures)
    if args.plot is not None and "PodPerComponent" in options.layouts:
        points = [
            plots.FleetPoint(
                robots=f.robots,
                coral_ready_s=f.times["PodPerComponent_ready"],
                coral_update_s=f.times["PodPerComponent_update"],
                daemonset_ready_s=f.times["daemonsets3_ready"],
                daemonset_update_s=f.times["daemonsets3_update"],
            )
            for f in figures
        ]
        note(f"plot: {plots.fleet_times(points, args.plot)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
