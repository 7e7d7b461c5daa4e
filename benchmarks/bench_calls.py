"""Benchmark: round trip of a behavior call into a skillset versus a raw rclpy service call.

Run by `make bench-calls` (part of `make bench`). Starts the example skillset as a real process,
then, in this process and against the same `~/count` service (no work delay):
  - raw: an rclpy client on a node spun by a background SingleThreadedExecutor, one call at a
    time, from `call_async` to the next `call_async`;
  - behavior: the executor's own machinery (ExecutorContext, plugin discovery and isolated
    loading, TickLoop with wake-ups, at a rate the calls never reach) running
    `<Repeat><Count/></Repeat>`; one sample is the time between consecutive starts of `Count`,
    i.e. request, response, wake-up, tick.
Rounds alternate so machine load hits both alike. Prints BENCH lines (DESIGN section 8).
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from coral_testbed.missions import domains

CALLS_PER_ROUND = 300
ROUNDS = 3
WARMUP = 30
TARGET_RATIO = 1.5
TREE = """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main"><Repeat num_cycles="{cycles}"><Count count="{{c}}"/></Repeat></BehaviorTree>
</root>"""


def _start_skillset(plugins: Path) -> subprocess.Popen[bytes]:
    process = subprocess.Popen(
        [sys.executable, "-m", "coral_skillsets.examples", "--plugins", str(plugins)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    deadline = time.monotonic() + 60
    while not (plugins / "examples" / "ready").exists():
        if process.poll() is not None or time.monotonic() > deadline:
            raise RuntimeError("the example skillset did not become ready")
        time.sleep(0.05)
    return process


def _raw_round(context: Any, calls: int) -> list[float]:
    from std_srvs.srv import Trigger

    client = context.service_client(Trigger, "/examples/count")
    if not client.wait_for_service(timeout_sec=30):
        raise RuntimeError("service /examples/count not found")
    done = threading.Event()
    starts: list[float] = []
    for _ in range(calls + 1):
        done.clear()
        starts.append(time.perf_counter())
        future = client.call_async(Trigger.Request())
        future.add_done_callback(lambda _f: done.set())
        if not done.wait(10):
            raise RuntimeError("raw call timed out")
    return [b - a for a, b in zip(starts, starts[1:], strict=False)]


def _behavior_round(context: Any, plugins: Path, calls: int) -> list[float]:
    from coral import coordination
    from coral.executor import plugins_phase, sinks
    from coral.executor.ticking import TickLoop
    from coral.plugins import compat
    from coral_core import bt

    document = bt.load_tree_text(TREE.format(cycles=calls + 1))
    registry = bt.NodeRegistry.with_builtins()
    coordination.register(registry)
    state = plugins_phase.PluginState(used=document.node_types_used(), builtin_ids=set(registry.node_ids()))
    plugins_phase.refresh(state, registry, plugins, compat.current_ros_distro())
    tree = bt.build_tree(document, registry, context=context)
    context.wake_up = tree.wake_up
    starts: list[float] = []

    def on_transition(transition: Any) -> None:
        if transition.node_id == "Count" and transition.status == bt.Status.RUNNING:
            starts.append(time.perf_counter())

    tree.add_transition_listener(on_transition)
    # The rate bounds the ticks, wake-ups included; a period far below the round trip keeps that
    # bound out of what is measured, the call's path.
    loop = TickLoop(tree, context, sinks.SinkFanout([]), state, rate_hz=1_000_000.0)
    if loop.run(threading.Event(), lambda: 4) != 0:
        raise RuntimeError("the benchmark tree did not succeed")
    return [b - a for a, b in zip(starts, starts[1:], strict=False)]


def main() -> int:
    domain, _lock = domains.claim_domain(highest_first=True)  # held until this process exits
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    from coral.executor.context import ExecutorContext

    with tempfile.TemporaryDirectory() as folder:
        plugins = Path(folder) / "plugins"
        skillset = _start_skillset(plugins)
        context = ExecutorContext(node_name="bench_calls", hostname="bench")
        try:
            _raw_round(context, WARMUP)
            _behavior_round(context, plugins, WARMUP)
            raw: list[float] = []
            behavior: list[float] = []
            for _ in range(ROUNDS):
                raw += _raw_round(context, CALLS_PER_ROUND)
                behavior += _behavior_round(context, plugins, CALLS_PER_ROUND)
        finally:
            context.shutdown()
            skillset.terminate()
            skillset.wait(timeout=10)
    raw_ms = statistics.median(raw) * 1000
    behavior_ms = statistics.median(behavior) * 1000
    ratio = behavior_ms / raw_ms
    ok = "ok" if ratio <= TARGET_RATIO else "miss"
    print(f"BENCH name=raw_rclpy_service_call_median value={raw_ms:.3f} unit=ms target=>0 result=ok")
    print(
        f"BENCH name=behavior_call_roundtrip_median value={behavior_ms:.3f} unit=ms "
        f"target=<={raw_ms * TARGET_RATIO:.3f} result={ok}"
    )
    print(
        f"BENCH name=behavior_call_vs_raw_ratio value={ratio:.3f} unit=x target=<={TARGET_RATIO} result={ok}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
