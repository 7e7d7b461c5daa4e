"""`coral demo --mission site`: the mixed fleet of examples/site on its own kind cluster.

Four robots of different models run one CoralSystem; its overrides give each model its components
and tree. The demo labels the robots' Nodes, applies the example, follows every robot's tree to
its end and deletes the cluster; afterwards nothing of it may be left.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from coral_testbed.images import registry
from coral_testbed.kind import clusters, engine, missions, provisioning
from coral_testbed.missions import demo, manifests

pytestmark = [pytest.mark.slow, pytest.mark.ros]

CLUSTER = missions.DEMO_CLUSTERS["site"]


@pytest.mark.timeout(1500)
def test_the_site_demo_ends_in_success_on_four_robots_of_their_own_models(tmp_path: Path) -> None:
    reason = provisioning.unsupported_reason()
    if reason:
        pytest.skip(reason)
    lines: list[str] = []

    def echo(line: str) -> None:
        # Printed as well, so the captured output of a failure shows how far the demo got.
        lines.append(line)
        print(line, flush=True)

    outcome = demo.run("site", 40, timeout=600, echo=echo, tree_png=tmp_path / "site.png")
    output = "\n".join(lines)
    assert outcome.roots == dict.fromkeys(manifests.SITE_ROBOTS, "SUCCESS"), output
    assert lines[-1].startswith("==> Demo finished in ") and lines[-1].endswith(": SUCCESS"), output
    # The survey's map reached the share, and no robot got there through a Fallback.
    share = next(line for line in lines if line.startswith("Site share"))
    assert "site_map.ply" in share.split(":", 1)[1].strip().split(", "), output
    for fallback in ("KeepMapOnRobot", "ReportSiteIncomplete", "InspectWithoutMap", "ArmStaysParked"):
        assert fallback not in output, output
    # Each model ran its own components, on its own robot (the demo's `kubectl get pods -o wide`).
    pods = output.split("$ kubectl get pods -A -o wide")[-1].splitlines()
    for robot, component in (
        ("site-survey", "slam"),
        ("site-quadruped", "localizer"),
        ("site-arm", "gripper"),
    ):
        assert any(component in line and robot in line for line in pods), (robot, component, output)
    for robot in manifests.SITE_ROBOTS:
        assert (tmp_path / f"site-{robot}.png").is_file(), robot
    _assert_nothing_left()


def _assert_nothing_left() -> None:
    assert not registry.recorded_addresses(clusters.state_dir(CLUSTER)), "the cluster's registry still runs"
    if not engine.project_engine_running():
        assert not engine.leftover_cgroups(), "cgroups of the project's dockerd are left"
        return
    # Another user's dockerd, running before the demo, stays up; only the demo's cluster must be gone.
    node_engine = engine.start(lambda _: None)
    assert not node_engine.containers(f"{clusters.KIND_CLUSTER_LABEL}={CLUSTER}"), "node containers left"
    networks = node_engine.docker("network", "ls", "--format", "{{.Name}}").stdout.split()
    assert clusters.network_name(CLUSTER) not in networks
