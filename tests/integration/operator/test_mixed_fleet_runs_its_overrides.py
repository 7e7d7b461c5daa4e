"""A fleet of three robot models under one CoralSystem: each model gets its own pods, a change to one
model's override rolls out to that model only, and `coral config` prints what each robot runs."""

from __future__ import annotations

import json
import subprocess
import sys
from typing import Any

import pytest
from coral_api import condition, is_current_and_true
from coral_core import names
from scenarios import Scenario

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

SPOT_SLAM = "coral/slam-skillset:spot-1"


def _overrides(spot_slam: str) -> list[dict[str, Any]]:
    return [
        {
            "name": "spot",
            "robots": {"matchLabels": {"coral.dev/model": "spot"}},
            "images": {"slam": spot_slam},
            "parameters": "slam:\n  ros__parameters:\n    max_range: 60.0\n",
        },
        {
            "name": "arm",
            "robots": {"matchLabels": {"coral.dev/model": "arm"}},
            "remove": ["lidar-driver"],
            "add": {"drivers": [{"name": "gripper", "image": "coral/bag-player:0.1.0"}]},
        },
        {
            "name": "server",
            "robots": {"matchLabels": {"coral.dev/model": "server"}},
            "remove": ["lidar-driver", "slam"],
            "env": [{"name": "ROBOT_IP", "value": "${robot.annotations['coral.dev/ip']}"}],
        },
    ]


def _running(scenario: Scenario) -> dict[str, dict[str, tuple[str, str]]]:
    """Robot -> component -> (image, pod uid) of the pods not being deleted."""
    found: dict[str, dict[str, tuple[str, str]]] = {}
    for pod in scenario.coral.pods().values():
        if pod.metadata.deletion_timestamp is None:
            labels = pod.metadata.labels
            found.setdefault(labels["coral.dev/robot"], {})[labels["coral.dev/component"]] = (
                pod.spec.containers[0].image,
                pod.metadata.uid,
            )
    return found


def _coral_config(scenario: Scenario, robot: str) -> dict[str, Any]:
    argv = [sys.executable, "-m", "coral", "config", "site", robot, "-n", scenario.namespace, "-o", "json"]
    done = subprocess.run(argv, env=scenario.cluster.env(), capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr + done.stdout
    return json.loads(done.stdout)


def test_each_model_runs_its_own_and_an_override_change_reaches_its_model_only(scenario: Scenario) -> None:
    labels = {"fleet": scenario.fleet_label}
    spots = scenario.make_robots(2, {**labels, "coral.dev/model": "spot"}, start=1)
    arms = scenario.make_robots(2, {**labels, "coral.dev/model": "arm"}, start=3)
    (server,) = scenario.make_robots(1, {**labels, "coral.dev/model": "server"}, start=5)
    scenario.cluster.kubectl("annotate", "node", server, "coral.dev/ip=10.1.2.3")
    manifest = scenario.mission("site")
    manifest["spec"]["rollout"] = {"maxUnavailable": 1}
    manifest["spec"]["overrides"] = _overrides(SPOT_SLAM)
    scenario.deploy(manifest)

    before = _running(scenario)
    for spot in spots:
        assert {c: image for c, (image, _) in before[spot].items()} == {
            "lidar-driver": "coral/bag-player:0.1.0",
            "slam": SPOT_SLAM,
            "executor": "coral/executor:0.1.0",
        }
    for arm in arms:
        assert set(before[arm]) == {"gripper", "slam", "executor"}
    assert set(before[server]) == {"executor"}
    executor = next(
        p for p in scenario.coral.pods().values() if p.metadata.labels["coral.dev/robot"] == server
    )
    assert {"ROBOT_IP": "10.1.2.3"}.items() <= {
        e.name: e.value for e in executor.spec.containers[0].env
    }.items()
    hashes = {i["spec"]["robot"]: i["spec"]["configHash"] for i in scenario.coral.instances().values()}
    assert hashes[spots[0]] == hashes[spots[1]] and hashes[arms[0]] == hashes[arms[1]]
    assert len({hashes[spots[0]], hashes[arms[0]], hashes[server]}) == 3

    # `coral config` prints what each robot runs, and that it runs it.
    for robot, components in ((spots[0], ["lidar-driver", "slam", "executor"]), (server, ["executor"])):
        said = _coral_config(scenario, robot)
        assert said["valid"] and said["configHash"] == hashes[robot] == said["running"]["configHash"]
        assert [c["name"] for c in said["components"]] == components
    said = _coral_config(scenario, spots[1])
    assert (
        "max_range: 60.0" in said["parameters"] and '<BehaviorTree ID="Patrol">' in said["tree"]["tree.xml"]
    )
    assert _coral_config(scenario, server)["components"][0]["env"]["ROBOT_IP"] == "10.1.2.3"
    argv = [sys.executable, "-m", "coral", "config", "site", arms[0], "-n", scenario.namespace]
    text = subprocess.run(argv, env=scenario.cluster.env(), capture_output=True, text=True, timeout=60).stdout
    assert "overrides: arm" in text and "running: this configuration" in text
    assert "driver    gripper" in text and "lidar-driver" not in text

    # Only the spots' override changes: only their slam pods are replaced.
    generation = scenario.coral.system("site")["metadata"]["generation"]
    scenario.coral.patch_system("site", {"spec": {"overrides": _overrides("coral/slam-skillset:spot-2")}})

    def rolled_out() -> bool:
        system = scenario.coral.system("site")
        running = _running(scenario)
        return (
            system["metadata"]["generation"] > generation
            and is_current_and_true(system, "Ready")
            and all(running.get(s, {}).get("slam", ("",))[0] == "coral/slam-skillset:spot-2" for s in spots)
        )

    scenario.wait(rolled_out, "the spots to run the new slam image and the system to be Ready")
    after = _running(scenario)
    for robot in [*arms, server]:
        assert after[robot] == before[robot], (
            f"{robot} was restarted although its configuration did not change"
        )
    for spot in spots:
        assert after[spot]["slam"][1] != before[spot]["slam"][1]
        assert after[spot]["executor"] == before[spot]["executor"]
    instances = {i["spec"]["robot"]: i["spec"] for i in scenario.coral.instances().values()}
    revision = scenario.coral.system("site")["status"]["revision"]
    assert {spec["revision"] for spec in instances.values()} == {revision}
    assert {r: instances[r]["configHash"] for r in [*arms, server]} == {r: hashes[r] for r in [*arms, server]}
    assert instances[spots[0]]["configHash"] != hashes[spots[0]]
    said = _coral_config(scenario, spots[0])
    assert said["configHash"] == said["running"]["configHash"]
    assert {c["name"]: c["image"] for c in said["components"]}["slam"] == "coral/slam-skillset:spot-2"

    # A second override that sets the server's variable differently: the server keeps what it
    # runs and the system names it with both overrides, while the others stay as they are.
    conflicting = {
        "name": "lab",
        "robots": {"matchLabels": {"coral.dev/model": "server"}},
        "env": [{"name": "ROBOT_IP", "value": "10.9.9.9"}],
    }
    overrides = [*_overrides("coral/slam-skillset:spot-2"), conflicting]
    scenario.coral.patch_system("site", {"spec": {"overrides": overrides}})

    def stalled() -> dict[str, Any] | None:
        system = scenario.coral.system("site")
        return system if is_current_and_true(system, "Stalled") else None

    system = scenario.wait(stalled, "the system to be Stalled naming the server")
    message = condition(system, "Stalled")["message"]
    assert condition(system, "Stalled")["reason"] == "InvalidRobotConfig"
    assert f"robot {server}: spec.overrides[lab].env[ROBOT_IP]" in message and "override server" in message
    assert _running(scenario) == after
    said = subprocess.run(
        [sys.executable, "-m", "coral", "config", "site", server, "-n", scenario.namespace],
        env=scenario.cluster.env(),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert said.returncode == 1 and "INVALID" in said.stdout


def test_coral_config_reads_parameters_from_a_source_config_map_and_only_from_one(scenario: Scenario) -> None:
    (robot,) = scenario.make_robots(1, {"fleet": scenario.fleet_label, "coral.dev/model": "spot"})
    manifest = scenario.mission("site")
    parameters = manifest["spec"]["parameters"].pop("inline")
    manifest["spec"]["parameters"]["configMapRef"] = {"name": "site-params", "key": "params.yaml"}
    manifest["spec"]["overrides"] = _overrides(SPOT_SLAM)[:1]
    scenario.coral.core.create_namespaced_config_map(
        scenario.namespace,
        {
            "metadata": {"name": "site-params", "labels": {names.LABEL_SOURCE: "true"}},
            "data": {"params.yaml": parameters},
        },
    )
    scenario.deploy(manifest)
    said = _coral_config(scenario, robot)
    assert "max_range: 60.0" in said["parameters"] and "done_topic: /bag_player/done" in said["parameters"]
    assert said["configHash"] == said["running"]["configHash"]

    # Without its owners' consent the operator reads nothing from it, and neither does `coral config`.
    scenario.coral.core.patch_namespaced_config_map(
        "site-params", scenario.namespace, {"metadata": {"labels": {names.LABEL_SOURCE: None}}}
    )
    argv = [sys.executable, "-m", "coral", "config", "site", robot, "-n", scenario.namespace]
    done = subprocess.run(argv, env=scenario.cluster.env(), capture_output=True, text=True, timeout=60)
    assert done.returncode != 0 and "not marked as a Coral source" in done.stderr
