"""CRs breaking a CEL rule are rejected at admission; a bad tree stalls the system and deploys nothing."""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import pytest
import yaml
from coral_api import condition, fleet_mission, is_current_and_true
from coral_testbed.waiting import holds_for
from scenarios import Scenario

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

BAD_TREE = '<root BTCPP_format="4">\n  <BehaviorTree ID="Main">\n    <Sequence>\n  </BehaviorTree>\n</root>\n'


def _variant(change: Callable[[dict[str, Any]], None]) -> dict[str, Any]:
    manifest = copy.deepcopy(fleet_mission("bad", "nobody"))
    change(manifest["spec"])
    return manifest


REJECTIONS = [
    (
        "privileged skillset",
        lambda s: s["skillsets"][0].update(privileged=True),
        "privileged is allowed only on drivers",
    ),
    (
        "duplicate component names",
        lambda s: s["executors"][0].update(name="slam"),
        "component names must be unique across drivers, skillsets and executors",
    ),
    (
        "empty robot selector",
        lambda s: s.update(robots={}),
        "robots must select with at least one label or expression",
    ),
    (
        "domain out of range",
        lambda s: s.update(ros={"domainId": 300}),
        "ros.domainId must be between 0 and 232",
    ),
    (
        "tree inline and from a ConfigMap",
        lambda s: s["tree"].update(configMapRef={"name": "x", "key": "tree.xml"}),
        "set exactly one of inline or configMapRef",
    ),
    (
        "In without values",
        lambda s: s.update(robots={"matchExpressions": [{"key": "fleet", "operator": "In", "values": []}]}),
        "operator In and NotIn need at least one value",
    ),
    (
        "Exists with values",
        lambda s: s.update(
            robots={"matchExpressions": [{"key": "fleet", "operator": "Exists", "values": ["a"]}]}
        ),
        "operator Exists and DoesNotExist take no values",
    ),
    (
        "a label key that is not one",
        lambda s: s.update(robots={"matchLabels": {"not a key!": "a"}}),
        "matchLabels keys and values must be Kubernetes label keys and values",
    ),
    (
        "a label value that is not one",
        lambda s: s.update(robots={"matchLabels": {"fleet": "not a value!"}}),
        "spec.robots.matchLabels.fleet",
    ),
    (
        "maxUnavailable in words",
        lambda s: s.update(rollout={"maxUnavailable": "lots"}),
        "rollout.maxUnavailable must be a count of at least 0 or a percentage like '10%'",
    ),
    (
        "two executors' Groot2 port pairs overlapping",
        lambda s: s.update(
            executors=[
                {**s["executors"][0], "groot2": {"port": 1667}},
                {**s["executors"][0], "name": "second", "groot2": {"port": 1668}},
            ]
        ),
        "executors' groot2 ports must be at least 2 apart",
    ),
    (
        "a Groot2 port only root may bind",
        lambda s: s["executors"][0].update(groot2={"port": 80}),
        "spec.executors[0].groot2.port",
    ),
    (
        "an include file under the tree's own name",
        lambda s: s["tree"].update(files={"tree.xml": "<root/>"}),
        "tree.files names must be file names",
    ),
    (
        "two overrides of one name",
        lambda s: s.update(
            overrides=[{"name": "spot", "robots": {"matchLabels": {"m": "a"}}, "env": []}] * 2
        ),
        "overrides must have unique names",
    ),
    (
        "an override selecting nothing",
        lambda s: s.update(overrides=[{"name": "spot", "robots": {}}]),
        "overrides[].robots must select with at least one label or expression",
    ),
]


@pytest.mark.parametrize(("story", "change", "message"), REJECTIONS, ids=[r[0] for r in REJECTIONS])
def test_the_api_server_rejects_what_the_cel_rules_forbid(
    cluster: Any,
    namespace: str,
    coral_crds: None,
    story: str,
    change: Callable[[dict[str, Any]], None],
    message: str,
) -> None:
    result = cluster.kubectl(
        "apply", "-n", namespace, "-f", "-", input=yaml.safe_dump(_variant(change)), check=False
    )
    assert result.returncode != 0
    assert message in result.stderr
    assert "coralsystems" not in cluster.kubectl("get", "coralsystems", "-n", namespace, "-o", "name").stdout


def test_a_bad_tree_stalls_with_file_and_line_and_robots_keep_what_they_ran(scenario: Scenario) -> None:
    coral, wait = scenario.coral, scenario.wait
    scenario.robots(1)

    broken = scenario.mission("broken")
    broken["spec"]["tree"] = {"inline": BAD_TREE}
    coral.create_system(broken)
    stalled = wait(
        lambda: (
            condition(coral.system("broken"), "Stalled").get("status") == "True" and coral.system("broken")
        ),
        "the broken system to be Stalled",
    )
    assert "coralsystem/broken spec.tree.inline:4:" in condition(stalled, "Stalled")["message"]
    assert condition(stalled, "Ready")["status"] == "False"
    assert not coral.instances() and not coral.pods()

    # A running system whose tree breaks keeps its pods and revision, and says why.
    scenario.deploy(scenario.mission("good"))
    running = {n: p.metadata.uid for n, p in coral.pods().items() if n.startswith("good-")}
    revision = coral.system("good")["status"]["revision"]
    coral.patch_system("good", {"spec": {"tree": {"inline": BAD_TREE}}})
    wait(
        lambda: is_current_and_true(coral.system("good"), "Stalled"),
        "the edited system to be Stalled at its new generation",
    )
    message = condition(coral.system("good"), "Stalled")["message"]
    assert "spec.tree.inline:4:" in message
    holds_for(
        lambda: (
            {n: p.metadata.uid for n, p in coral.pods().items() if n.startswith("good-")} == running
            and {i["spec"]["revision"] for i in coral.instances().values() if i["spec"]["system"] == "good"}
            == {revision}
        ),
        duration=4,
        message="the robots keeping their pods and revision",
    )
