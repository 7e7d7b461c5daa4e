"""Preflight on a cluster: the operator reads what the component images declare from a real registry
(the project's local docker-registry, over the HTTP API v2) and refuses a tree those images cannot
run before any CoralInstance or pod exists, naming the image and the tree's file:line; a good
change then rolls out. `coral verify --registry` gives CI the same verdicts.

The images pushed here hold only a config (their labels) and no layers: the registry serves them
as any image, and kwok robots never pull. Their declarations are the runtime manifests of the
project's own skillset and driver (`coral verify` of the installed components).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
from coral.local import checking
from coral_api import condition, is_current_and_true
from coral_core.image_exports import EXPORTS_LABEL, DeclaredBehavior, ImageExports
from coral_operator.api.system import CoralSystemSpec
from coral_operator.kube import observing
from coral_operator.planning import preflight
from coral_operator.planning.observed import RobotNode
from coral_operator.reconcile.declarations import ImageDeclarations
from coral_testbed.images import registry
from fixtures.system_passes import plan_system_pass
from scenarios import Scenario

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

_MANIFEST = "application/vnd.oci.image.manifest.v1+json"


def push_labelled(address: str, reference: str, labels: dict[str, str]) -> str:
    """Push an image of no layers whose config carries `labels`; its manifest digest."""
    repository, _, tag = reference.partition(":")
    config = json.dumps(
        {
            "architecture": "amd64",
            "os": "linux",
            "config": {"Labels": labels},
            "rootfs": {"type": "layers", "diff_ids": []},
        }
    ).encode()
    config_digest = registry.put_blob(address, repository, config)
    manifest = {
        "schemaVersion": 2,
        "mediaType": _MANIFEST,
        "config": {
            "mediaType": "application/vnd.oci.image.config.v1+json",
            "digest": config_digest,
            "size": len(config),
        },
        "layers": [],
    }
    return registry.put_manifest(address, repository, tag, manifest, _MANIFEST)


def _declared(component: str) -> ImageExports:
    result = checking.verify_component(component)
    assert result.ok, result.problems
    return result.manifest.image_exports()  # type: ignore[attr-defined]


@pytest.fixture(scope="module")
def preflight_registry(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A registry of its own on a free loopback port, holding the images this module pushes."""
    address = registry.free_address()
    process = registry.start(
        address, tmp_path_factory.mktemp("storage"), tmp_path_factory.mktemp("registry"), die_with_parent=True
    )
    slam, lidar = _declared("coral/slam-skillset:0.1.0"), _declared("coral/bag-player:0.1.0")
    push_labelled(address, "coral/slam-skillset:0.1.0", {EXPORTS_LABEL: slam.to_label()})
    push_labelled(address, "coral/bag-player:0.1.0", {EXPORTS_LABEL: lidar.to_label()})
    push_labelled(
        address, "coral/slam-skillset:next", {EXPORTS_LABEL: replace(slam, coral_version="1.0.0").to_label()}
    )
    push_labelled(address, "coral/plain:1", {"org.opencontainers.image.title": "plain"})
    push_labelled(address, "coral/fleet-0:1", {EXPORTS_LABEL: slam.to_label()})
    for i in range(1, 5):
        skill = replace(slam, component=f"s{i}", behaviors=(DeclaredBehavior(f"Skill{i}", "action"),))
        push_labelled(address, f"coral/fleet-{i}:1", {EXPORTS_LABEL: skill.to_label()})
    yield address
    registry.stop(process)


@pytest.fixture(scope="module")
def operator_env(preflight_registry: str) -> dict[str, str]:
    return {"CORAL_PREFLIGHT_REGISTRIES": preflight_registry}


def _mission(
    scenario: Scenario, address: str, leaf: str, slam: str = "coral/slam-skillset:0.1.0"
) -> dict[str, Any]:
    manifest = scenario.mission("site")
    spec = manifest["spec"]
    spec["tree"]["inline"] = spec["tree"]["inline"].replace("<EnableLocalization/>", leaf)
    spec["drivers"][0]["image"] = f"{address}/coral/bag-player:0.1.0"
    spec["skillsets"][0]["image"] = f"{address}/{slam}"
    return manifest


def _refused(scenario: Scenario, generation: int) -> dict[str, Any]:
    def stalled() -> dict[str, Any] | None:
        system = scenario.coral.system("site")
        stall = condition(system, "Stalled")
        current = system is not None and stall.get("observedGeneration") == generation
        return stall if current and stall.get("reason") == "PreflightFailed" else None

    return scenario.wait(stalled, "the system to be Stalled by preflight")


def test_preflight_refuses_what_the_images_cannot_run_before_any_pod(
    scenario: Scenario, preflight_registry: str
) -> None:
    address = preflight_registry
    scenario.make_robots(3, {"fleet": scenario.fleet_label})
    cases = [
        (
            "<Fly/>",
            "coral/slam-skillset:0.1.0",
            "spec.tree.inline:4: behavior Fly is exported by none of the images",
        ),
        (
            '<EnableLocalization speed="3"/>',
            "coral/slam-skillset:0.1.0",
            f"port [speed] of EnableLocalization is not declared by image {address}/coral/slam-skillset:",
        ),
        (
            "<EnableLocalization/>",
            "coral/slam-skillset:next",
            f"image {address}/coral/slam-skillset:next was built for Coral 1.0.0",
        ),
    ]
    scenario.coral.create_system(_mission(scenario, address, cases[0][0], cases[0][1]))
    for i, (leaf, slam, expected) in enumerate(cases):
        if i:
            spec = _mission(scenario, address, leaf, slam)["spec"]
            scenario.coral.patch_system(
                "site", {"spec": {"tree": spec["tree"], "skillsets": spec["skillsets"]}}
            )
        generation = scenario.coral.system("site")["metadata"]["generation"]
        stall = _refused(scenario, generation)
        assert expected in stall["message"], stall["message"]
        assert scenario.coral.instances() == {} and scenario.coral.pods() == {}

    good = _mission(scenario, address, "<EnableLocalization/>")["spec"]
    started = time.monotonic()
    scenario.coral.patch_system("site", {"spec": {"tree": good["tree"], "skillsets": good["skillsets"]}})
    generation = scenario.coral.system("site")["metadata"]["generation"]
    scenario.wait(
        lambda: (
            is_current_and_true(scenario.coral.system("site"), "Ready")
            and scenario.coral.system("site")["metadata"]["generation"] == generation
        ),
        "the good change to roll out",
    )
    print(f"preflight: refusals then a good change, Ready in {time.monotonic() - started:.1f} s")
    assert len(scenario.coral.instances()) == 3


def test_coral_verify_reads_the_registry_as_the_operator_does(
    preflight_registry: str, tmp_path: Path
) -> None:
    address = preflight_registry
    tree = tmp_path / "mission.xml"
    tree.write_text(
        '<root BTCPP_format="4">\n  <BehaviorTree ID="Main">\n    <Sequence>\n'
        "      <EnableLocalization/>\n      <Fly/>\n    </Sequence>\n  </BehaviorTree>\n</root>\n"
    )

    def verify(*args: str) -> subprocess.CompletedProcess[str]:
        argv = [sys.executable, "-m", "coral", "verify", "--registry", *args]
        return subprocess.run(argv, capture_output=True, text=True, timeout=60)

    refused = verify(f"{address}/coral/slam-skillset:0.1.0", "--tree", str(tree))
    assert refused.returncode == 1, refused.stdout + refused.stderr
    assert (
        f"{tree}:5: behavior Fly is exported by none of the images {address}/coral/slam-skillset:0.1.0@"
        in refused.stderr
    )
    assert "skillset slam, Coral 0.1.0, BT.CPP 4, ROS" in refused.stdout
    tree.write_text(tree.read_text().replace("      <Fly/>\n", ""))
    passed = verify(
        f"{address}/coral/slam-skillset:0.1.0", f"{address}/coral/bag-player:0.1.0", "--tree", str(tree)
    )
    assert passed.returncode == 0, passed.stdout + passed.stderr
    old = verify(f"{address}/coral/slam-skillset:next")
    assert old.returncode == 1 and "was built for Coral 1.0.0" in old.stderr
    plain = verify(f"{address}/coral/plain:1", "--tree", str(tree))
    assert plain.returncode == 0 and "declares nothing" in plain.stdout
    missing = verify(f"{address}/coral/none:1")
    assert missing.returncode == 1 and "answered 404" in missing.stderr


def test_a_hundred_robots_on_five_images_preflight_in_under_five_seconds(preflight_registry: str) -> None:
    """The operator's read and check of one system pass, from a cold cache and then warm."""
    address = preflight_registry
    images = [f"{address}/coral/fleet-{i}:1" for i in range(5)]
    spec: dict[str, Any] = {
        "robots": {"matchLabels": {"fleet": "big"}},
        "parameters": {"inline": "slam:\n  ros__parameters:\n    max_range: 30.0\n"},
        "tree": {
            "inline": '<root BTCPP_format="4"><BehaviorTree ID="Main"><Sequence>'
            '<EnableLocalization/><ProcessScan scans_processed="{s}" pose="{p}"/><Skill1/>'
            "</Sequence></BehaviorTree></root>"
        },
        "skillsets": [{"name": f"s{i}", "image": image} for i, image in enumerate(images[:3])],
        "executors": [{"name": "executor", "image": "coral/executor:0.1.0"}],
        "overrides": [
            {"name": f"m{m}", "robots": {"matchLabels": {"model": f"m{m}"}}, "images": {"s2": images[3 + m]}}
            for m in range(2)
        ],
    }
    robots = [
        RobotNode(node_name=f"r{i}", robot=f"r{i}", labels={"fleet": "big", "model": f"m{i % 3}"}, ready=True)
        for i in range(100)
    ]
    record = observing.system_record(
        {"metadata": {"name": "big", "namespace": "ns", "uid": "u", "generation": 1}, "spec": spec}
    )
    parsed = CoralSystemSpec.model_validate(spec)
    declarations = ImageDeclarations(registries=frozenset({address}))
    timings = []
    for _ in range(2):
        started = time.monotonic()
        table = declarations.read(preflight.images_to_read(parsed))
        plan = plan_system_pass(record, spec, robots, now=datetime.now(UTC), images=table)
        timings.append(time.monotonic() - started)
        assert plan.problem is None and len(plan.changes.create) == 100 and plan.preflight_notes == []
    assert declarations.labels.reads == 5
    print(
        f"BENCH name=preflight_100_robots_5_images_cold value={timings[0]:.3f} unit=s target=<5 "
        f"result={'ok' if timings[0] < 5 else 'fail'}"
    )
    print(f"BENCH name=preflight_100_robots_5_images_warm value={timings[1]:.3f} unit=s target=<5 result=ok")
    assert max(timings) < 5
