"""What one CoralSystem expands to across its robots, and what one namespace holds, are bounded.

Issue 47: one 0.7 MB CoralSystem matching 40 robots became 56 MB of instances and pods, and the
operator kept 2.85 MB per robot. Strings are capped by the schema; their sum per robot, times the
robots, and per namespace are checked by the operator, each refusal naming the figures.
"""

from __future__ import annotations

import copy
import json
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
import yaml
from coral_operator.api.system import CoralSystemSpec
from coral_operator.kube import observing
from coral_operator.planning import budgets, system_pass
from coral_operator.planning.policy import Policy
from coral_operator.status.conditions import Reason
from fixtures.system_passes import fleet_robots, plan_system_pass
from pydantic import ValidationError

ROOT = Path(__file__).resolve().parents[3]
MISSION = yaml.safe_load((ROOT / "examples" / "fleet" / "mission.yaml").read_text())


def _spec(env_values: int = 0, value_size: int = 4096) -> dict[str, Any]:
    spec = copy.deepcopy(MISSION["spec"])
    spec["robots"] = {"matchLabels": {"fleet": "f"}}
    for component in spec["drivers"] + spec["skillsets"] + spec["executors"]:
        component["env"] = [{"name": f"V{i}", "value": "x" * value_size} for i in range(env_values)]
    return spec


def _record(name: str, spec: dict[str, Any], created: str = "2026-01-01T00:00:00Z") -> Any:
    return observing.system_record(
        {
            "metadata": {"name": name, "namespace": "ns", "uid": f"u-{name}", "creationTimestamp": created},
            "spec": spec,
        }
    )


def _plan(
    record: Any, robots: int, neighbours: list[budgets.Footprint] | None = None
) -> system_pass.SystemPlan:
    return plan_system_pass(
        record,
        record.spec,
        fleet_robots(robots),
        now=datetime(2026, 1, 1, tzinfo=UTC),
        policy=Policy(host_network_namespaces=frozenset({"*"}), host_paths=(("*", "/var/lib/coral/bags"),)),
        neighbours=neighbours,
    )


def test_an_env_value_longer_than_4096_characters_is_refused_by_the_schema() -> None:
    with pytest.raises(ValidationError) as refused:
        CoralSystemSpec.model_validate(_spec(env_values=1, value_size=4097))
    assert "at most 4096 characters" in str(refused.value)


def test_a_system_whose_robot_copy_passes_the_bound_is_refused_naming_the_figure() -> None:
    record = _record("big", _spec(env_values=12))
    assert record.share_bytes > budgets.MAX_ROBOT_SHARE_BYTES
    plan = _plan(record, robots=1)
    assert plan.problem is not None and plan.problem.reason == Reason.TOO_LARGE
    assert (
        f"{record.share_bytes:,} bytes are copied to every robot; the limit is 131,072"
        in plan.problem.message
    )
    assert plan.problem.message.startswith("spec.drivers, spec.skillsets and spec.executors")
    assert not plan.changes.create


def test_a_system_multiplied_past_the_bound_by_its_robots_is_refused_before_any_instance() -> None:
    record = _record("wide", _spec(env_values=8))
    robots = budgets.MAX_SYSTEM_EXPANSION_BYTES // record.share_bytes + 1
    plan = _plan(record, robots=robots)
    assert plan.problem is not None and plan.problem.reason == Reason.TOO_LARGE
    expanded = record.share_bytes * robots
    assert (
        f"{record.share_bytes:,} bytes copied to each of {robots:,} matched robots make {expanded:,} bytes; "
        f"the limit is 16,777,216" in plan.problem.message
    )
    assert plan.matched == robots and not plan.changes.create


def test_the_same_system_on_fewer_robots_is_deployed() -> None:
    record = _record("wide", _spec(env_values=8))
    plan = _plan(record, robots=budgets.MAX_SYSTEM_EXPANSION_BYTES // record.share_bytes)
    assert plan.problem is None and plan.changes.create


def test_the_newest_system_past_its_namespaces_total_is_refused_and_the_older_ones_are_not() -> None:
    record = _record("late", _spec(env_values=8), created="2026-01-02T00:00:00Z")
    older = [budgets.Footprint(f"s{i}", "2026-01-01T00:00:00Z", 1_000_000, 100_000, 40) for i in range(7)]
    plan = _plan(record, robots=1, neighbours=older)
    assert plan.problem is not None and plan.problem.reason == Reason.TOO_LARGE
    assert plan.problem.message.startswith("spec: the CoralSystems of namespace ns would hold ")
    assert "(7 older systems and this one's" in plan.problem.message
    assert plan.problem.message.endswith("the limit is 33,554,432")
    # An older system is not refused for a newer one.
    first = _record("s0", _spec(), created="2026-01-01T00:00:00Z")
    newer = [budgets.Footprint("late", "2026-01-02T00:00:00Z", 10_000_000, 100_000, 200)]
    assert _plan(first, robots=1, neighbours=[*older[1:], *newer]).problem is None


def test_two_hundred_maximal_systems_fit_in_ten_namespaces() -> None:
    """The load test's shape: 20 systems with parameters and tree at their admitted maximum per namespace."""
    maximal = budgets.Footprint("m", "", 3 * 256 * 1024 + 16 * 32 * 1024, budgets.MAX_ROBOT_SHARE_BYTES, 0)
    assert budgets.check_namespace("ns", maximal, [maximal] * 19) is None


def test_instances_of_one_revision_share_one_copy_of_their_spec() -> None:
    table = observing.SpecTable()
    spec = {
        "system": "s",
        "revision": "r1",
        "drivers": [{"name": "d", "env": [{"name": "A", "value": "x" * 4096}]}],
    }
    bodies = [
        json.loads(
            json.dumps(
                {"metadata": {"name": f"i{i}"}, "spec": {**spec, "robot": f"r{i}", "nodeName": f"n{i}"}}
            )
        )
        for i in range(3)
    ]
    specs = [table.share(body) for body in bodies]
    assert all(s["drivers"] is specs[0]["drivers"] for s in specs)
    assert [s["robot"] for s in specs] == ["r0", "r1", "r2"]
    assert specs[1] == bodies[1]["spec"] and len(table) == 1
    # A hand-written instance claiming the same revision with other content shares nothing.
    forged = table.share({"spec": {**spec, "drivers": [{"name": "d", "privileged": True}]}})
    assert forged["drivers"] is not specs[0]["drivers"] and len(table) == 2
    del specs, forged
    assert len(table) == 0


def test_large_inline_files_stay_out_of_the_index_but_count_in_the_spec_size() -> None:
    spec = _spec()
    spec["parameters"] = {"inline": "a:\n  ros__parameters: {x: 1}\n" + "#" * 200_000 + "\n"}
    spec["tree"]["files"] = {"nav.xml": "<root/>" + " " * 30_000}
    record = _record("files", spec)
    assert record.files_left_out
    assert record.spec["parameters"]["inline"] == "" and record.spec["tree"]["files"] == {"nav.xml": ""}
    assert record.spec["drivers"] == spec["drivers"]
    assert record.spec_bytes > 230_000
    kept = observing.system_record({"metadata": {"name": "files"}, "spec": spec}, keep_files=True)
    assert not kept.files_left_out and kept.spec["parameters"] == spec["parameters"]
    small = _record("small", _spec())
    assert not small.files_left_out and small.spec["tree"] == _spec()["tree"]
