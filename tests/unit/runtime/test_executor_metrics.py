"""The executor's metrics as Prometheus scrapes them over HTTP: ticks and their durations, the
root's status, behavior results and durations by node type, plugin libraries; named as Prometheus
expects (`promtool check metrics`), and the endpoint gone once the executor closes it."""

from __future__ import annotations

import shutil
import subprocess
import threading
import urllib.error
import urllib.request

import pytest
from coral.executor.metrics import ExecutorMetrics
from fixtures.prometheus import free_port
from prometheus_client import CollectorRegistry
from prometheus_client.parser import text_string_to_metric_families

from .test_tick_loop import Work
from .tree_fakes import Collect, FailsAtOnce, build_loop

TREE = """
<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Sequence>
      <Fallback>
        <FailsAtOnce/>
        <Work/>
      </Fallback>
      <Work/>
    </Sequence>
  </BehaviorTree>
</root>
"""


def _scrape(port: int) -> str:
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=5) as response:
        return str(response.read().decode())


def _samples(text: str) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    return {
        (sample.name, tuple(sorted(sample.labels.items()))): sample.value
        for family in text_string_to_metric_families(text)
        for sample in family.samples
    }


def test_a_mission_shows_its_ticks_root_status_and_behavior_results_on_the_endpoint() -> None:
    metrics = ExecutorMetrics(CollectorRegistry())
    port = free_port()
    metrics.serve("127.0.0.1", port)
    try:
        collect = Collect()
        loop = build_loop(
            TREE,
            collect,
            {"Work": Work, "FailsAtOnce": FailsAtOnce},
            rate_hz=50,
            on_tick=metrics.observe_tick,
        )
        loop.fanout.add(metrics)
        metrics.emit(
            {
                "event": "plugins",
                "loaded": [{"component": "s", "behaviors": ["Work"]}],
                "refused": [],
                "conflicts": [],
            }
        )
        assert loop.run(threading.Event(), lambda: 143) == 0
        text = _scrape(port)
    finally:
        metrics.close()
    samples = _samples(text)
    ticks = samples[("coral_executor_ticks_total", ())]
    assert ticks >= 2
    assert samples[("coral_executor_tick_duration_seconds_count", ())] == ticks
    assert samples[("coral_executor_tree_status", (("status", "SUCCESS"),))] == 1
    assert samples[("coral_executor_tree_status", (("status", "RUNNING"),))] == 0
    assert (
        samples[("coral_executor_behavior_results_total", (("behavior", "Work"), ("result", "SUCCESS")))] == 2
    )
    assert (
        samples[
            ("coral_executor_behavior_results_total", (("behavior", "FailsAtOnce"), ("result", "FAILURE")))
        ]
        == 1
    )
    # Work runs for Work.DELAY_S between its start and its result; FailsAtOnce never runs.
    work_time = samples[("coral_executor_behavior_duration_seconds_sum", (("behavior", "Work"),))]
    assert work_time >= 2 * Work.DELAY_S * 0.9
    assert samples[("coral_executor_behavior_duration_seconds_sum", (("behavior", "FailsAtOnce"),))] == 0
    assert samples[("coral_executor_plugins", (("state", "loaded"),))] == 1
    with pytest.raises(urllib.error.URLError):
        _scrape(port)
    promtool = shutil.which("promtool")
    if promtool is not None:
        checked = subprocess.run(
            [promtool, "check", "metrics"], input=text.encode(), capture_output=True, check=False
        )
        assert checked.returncode == 0 and not checked.stdout.strip(), (
            checked.stdout.decode() + checked.stderr.decode()
        )
