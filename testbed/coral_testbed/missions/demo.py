"""`coral demo` (what `make demo` runs): a mission on a kind cluster, end to end.

Makes a throwaway kind cluster whose workers are the robots (docs/kind.md), builds the mission's
images into its registry and installs the operator with Helm, copies the synthetic LiDAR bag into
the robot's files, `kubectl apply`s the committed example mission, prints every robot's tree as it
moves until the mission ends, shows `kubectl get coralinstances`, scores the map and the trajectory
against ground truth, and deletes everything it made, also on error or Ctrl-C.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from coral import tree_picture
from coral.lidar import demo as slam_demo
from coral.lidar import generating
from coral.local.console import outline_of
from coral_core import keys, names, terminal
from coral_core.component_image import COMPONENT_UID
from rich.live import Live

from coral_testbed.cluster.client import Cluster
from coral_testbed.kind import missions as kind_missions
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.missions import domains, following, manifests
from coral_testbed.missions.stack import OPERATOR_NODE, MissionView
from coral_testbed.waiting import wait_for

NAMESPACE = "coral-demo"
# Where the SLAM mission's map, trajectory and picture are kept after the demo's robots are gone.
DEFAULT_OUTPUT = Path("out/demo")
Echo = Callable[[str], None]


@dataclass(frozen=True)
class Outcome:
    roots: dict[str, str]
    """Robot -> the tree's final root status."""
    duration_s: float

    @property
    def success(self) -> bool:
        return bool(self.roots) and all(root == "SUCCESS" for root in self.roots.values())


def _kubectl(cluster: Cluster, echo: Echo, *args: str) -> None:
    echo(f"$ kubectl {' '.join(args)}")
    result = cluster.kubectl(*args, check=False)
    echo((result.stdout + result.stderr).rstrip())


def _apply(stack: KindMissionStack, mission: Path, domain: int, echo: Echo) -> None:
    shown = mission.relative_to(manifests.ROOT)
    echo(f"==> Applying {shown} on ROS domain {domain} (spec.ros.domainId; held by this demo, so no")
    echo("    other ROS process on this machine talks to its robots)")
    echo(f"$ kubectl apply -n {NAMESPACE} -f {shown}")
    echo(stack.apply(manifests.with_domain(mission.read_text(), domain)).rstrip())


def _follow(stack: KindMissionStack, robots: list[str], timeout: float, echo: Echo) -> dict[str, str]:
    echo(
        f"==> Following the CoralInstances' tree status (robot, root, ticks, active node),"
        f" up to {timeout:.0f} s"
    )

    def watch(**display: Any) -> list[dict[str, Any]]:
        return following.follow(
            stack.instances,
            lambda items: following.finished(items, robots),
            timeout=timeout,
            check=stack.check_operator,
            **display,
        )

    out = terminal.console()
    if out.is_terminal:
        # A table redrawn in place; it stays on the screen with the final statuses.
        with Live(following.table([]), console=out, auto_refresh=False) as live:
            instances = watch(show=lambda items: live.update(following.table(items), refresh=True))
    else:
        instances = watch(echo=echo)
    return {following.robot(i): str(following.tree(i).get(keys.TREE.root_status)) for i in instances}


def _await_executors_done(stack: KindMissionStack, echo: Echo, timeout: float = 30) -> None:
    """Waits (bounded) for the executor pods to exit, so the pod list shows the mission Completed."""

    def done() -> bool:
        pods = stack.core.list_namespaced_pod(stack.namespace, label_selector="coral.dev/role=executor").items
        return all(p.status.phase in ("Succeeded", "Failed") for p in pods)

    try:
        wait_for(done, timeout=timeout, interval=0.5, message="executor pods finished")
    except TimeoutError as error:
        echo(f"    ({error})")


def _slam(
    stack: KindMissionStack, dataset: Path, domain: int, timeout: float, echo: Echo, kept: Path
) -> dict[str, str]:
    link = stack.place_bag(manifests.SLAM_ROBOT, dataset / "bag", manifests.SLAM_BAG)
    echo(f"==> The bag is on {manifests.SLAM_ROBOT} at hostPath {manifests.SLAM_BAG} ({link})")
    _apply(stack, manifests.SLAM_MISSION, domain, echo)
    roots = _follow(stack, [manifests.SLAM_ROBOT], timeout, echo)
    _await_executors_done(stack, echo)
    _kubectl(stack.cluster, echo, "get", "coralsystems,coralinstances", "-n", NAMESPACE)
    _kubectl(stack.cluster, echo, "get", "pods", "-n", NAMESPACE, "-o", "wide")
    scratch = Path(tempfile.mkdtemp(prefix="coral-demo-output-"))
    try:
        output = stack.component_output(manifests.SLAM_ROBOT, "slam", scratch)
        if output is None:
            echo("No SLAM output folder: no map to score")
            return roots
        evaluation = keep_outputs(slam_demo.evaluate(output, dataset), kept)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    echo("")
    echo(f"Mission           : {roots.get(manifests.SLAM_ROBOT)} on {manifests.SLAM_ROBOT}")
    echo(f"SLAM output       : {output} (removed when the demo ends; kept below)")
    for line in evaluation.summary():
        echo(line)
    return roots


def keep_outputs(evaluation: slam_demo.Evaluation, folder: Path) -> slam_demo.Evaluation:
    """Copies the map, trajectory, stats and picture out of the robot's files (which go when the
    demo stops) into `folder`; the evaluation then names the copies."""
    folder.mkdir(parents=True, exist_ok=True)
    stem = evaluation.map_path.stem
    for path in evaluation.map_path.parent.glob(f"{stem}.*"):
        shutil.copy2(path, folder / path.name)
    picture = evaluation.picture_path
    return dataclasses.replace(
        evaluation,
        map_path=folder / evaluation.map_path.name,
        picture_path=folder / picture.name if picture is not None else None,
    )


def draw_trees(stack: MissionView, robots: list[str], target: Path, echo: Echo) -> None:
    """Draws each robot's deployed tree (from its instance's ConfigMap) coloured by what the
    instance reports; one robot gets `target`, several `<stem>-<robot>.png` beside it."""
    for robot in robots:
        instance = stack.instance_of(robot)
        if instance is None:
            echo(f"No CoralInstance for {robot}: no tree picture")
            continue
        spec = instance["spec"]["tree"]
        config_map = stack.core.read_namespaced_config_map(spec["configMap"], stack.namespace)
        with tempfile.TemporaryDirectory(prefix="coral-tree-") as folder:
            tree_file = Path(folder) / "tree.xml"
            tree_file.write_text(config_map.data["tree.xml"])
            outline = outline_of(tree_file, spec.get("mainTreeId"))
        path = target if len(robots) == 1 else target.with_name(f"{target.stem}-{robot}.png")
        status = following.tree(instance)
        root, ticks = status.get(keys.TREE.root_status), status.get(keys.TREE.tick_count, 0)
        title = f"{robot}: tree {root} after {ticks} ticks"
        tree_picture.draw_tree(outline, following.tree_statuses(instance), path, title)
        echo(f"Tree picture      : {path}")


def _coordinated(
    stack: KindMissionStack,
    mission: Path,
    robots: list[str],
    dataset: Path,
    domain: int,
    timeout: float,
    echo: Echo,
) -> dict[str, str]:
    """A mission of several robots: the first (the survey) maps the bag, the second (the server)
    exports the site share the others mount. Its results stay on the share, so nothing is kept."""
    survey, server, *others = robots
    stack.place_bag(survey, dataset / "bag", manifests.SURVEY_BAG)
    share = stack.share_folder(server, [survey, *others])
    echo(f"==> {server} exports {manifests.SITE_SHARE} ({share}); {', '.join([survey, *others])} mount it")
    _apply(stack, mission, domain, echo)
    roots = _follow(stack, robots, timeout, echo)
    _await_executors_done(stack, echo)
    _kubectl(stack.cluster, echo, "get", "coralsystems,coralinstances", "-n", NAMESPACE)
    echo("")
    for robot in robots:
        echo(f"{robot:<16}: {roots.get(robot)}")
    shared = sorted(p.name for p in share.iterdir())
    echo(f"Site share      : {', '.join(shared) or '(empty)'}")
    return roots


def _relay(
    stack: KindMissionStack, dataset: Path, domain: int, timeout: float, echo: Echo, kept: Path
) -> dict[str, str]:
    """The three-robot relay, one CoralSystem a robot."""
    return _coordinated(
        stack, manifests.RELAY_MISSION, list(manifests.RELAY_ROBOTS), dataset, domain, timeout, echo
    )


def _site(
    stack: KindMissionStack, dataset: Path, domain: int, timeout: float, echo: Echo, kept: Path
) -> dict[str, str]:
    """The mixed fleet: one CoralSystem whose overrides pick each robot's components and tree by the
    model label its Node carries, labelled here as an administrator would."""
    for robot, model in manifests.SITE_ROBOTS.items():
        _kubectl(
            stack.cluster,
            echo,
            "label",
            "node",
            "-l",
            f"{names.LABEL_ROBOT}={robot}",
            f"coral.dev/model={model}",
            manifests.SITE_LABEL,
        )
    return _coordinated(
        stack, manifests.SITE_MISSION, list(manifests.SITE_ROBOTS), dataset, domain, timeout, echo
    )


class DemoUnsupported(RuntimeError):
    """This machine cannot host the demo's kind cluster; the message says why and what to install."""


OnStack = Callable[[KindMissionStack], dict[str, str]]
"""Runs the mission on a started stack; returns each robot's final tree root status."""


def _run_on_kind(
    robots: list[str], folder: Path, echo: Echo, on_stack: OnStack, mission: str
) -> dict[str, str]:
    echo(f"==> A kind cluster: a control plane; robots {', '.join(robots)} and {OPERATOR_NODE} as workers")
    share = folder / "site-share"
    share.mkdir()
    # The components run as their own user and write the share, as on a site's NFS export.
    os.chown(share, COMPONENT_UID, COMPONENT_UID)
    with kind_missions.demo_cluster(robots, echo, share, kind_missions.DEMO_CLUSTERS[mission]) as (
        running,
        cluster,
    ):
        _kubectl(cluster, echo, "get", "nodes", "-o", "wide", "-L", "coral.dev/robot")
        with KindMissionStack(
            running, cluster, NAMESPACE, robots, folder / "mission", echo, share
        ) as stack:
            roots = on_stack(stack)
            _kubectl(cluster, echo, "get", "pods", "-A", "-o", "wide")
    return roots


def _check_kind() -> None:
    from coral_testbed.kind import provisioning

    missing = provisioning.unsupported_reason()
    if missing is not None:
        raise DemoUnsupported(f"the demo runs on a kind cluster, which this machine cannot host: {missing}")


RunMission = Callable[[KindMissionStack, Path, int, float, Echo, Path], dict[str, str]]
"""Runs a mission on a started stack (dataset, ROS domain, timeout, echo, where outputs are kept)."""
MISSIONS: dict[str, tuple[list[str], RunMission]] = {
    "slam": ([manifests.SLAM_ROBOT], _slam),
    "relay": (list(manifests.RELAY_ROBOTS), _relay),
    "site": (list(manifests.SITE_ROBOTS), _site),
}


def run(
    mission: str,
    scans: int,
    timeout: float,
    echo: Echo = print,
    tree_png: Path | None = None,
    output_dir: Path = DEFAULT_OUTPUT,
) -> Outcome:
    """Runs `mission` (a key of `MISSIONS`) from start to stop; see the module docstring.

    Raises:
        DemoUnsupported: this machine cannot host a kind cluster (checked before anything starts).
    """
    _check_kind()
    began = time.monotonic()
    params = generating.BagParams(scans=scans)
    echo(f"==> Synthetic LiDAR bag: {params.scans} scans (generated once, then cached)")
    with terminal.progress("    Generating the bag") as step:
        dataset = generating.cached_dataset(params, progress=step)
    echo(f"    {dataset / 'bag'}")
    robots, run_mission = MISSIONS[mission]
    roots: dict[str, str] = {}
    domain, lock = domains.claim_domain()

    def on_stack(stack: KindMissionStack) -> dict[str, str]:
        roots = run_mission(stack, dataset, domain, timeout, echo, output_dir.resolve())
        if tree_png is not None:
            draw_trees(stack, robots, tree_png.resolve(), echo)
        return roots

    try:
        with tempfile.TemporaryDirectory(prefix="coral-demo-") as folder:
            roots = _run_on_kind(robots, Path(folder), echo, on_stack, mission)
    finally:
        os.close(lock)
    outcome = Outcome(roots=roots, duration_s=time.monotonic() - began)
    verdict = "SUCCESS" if outcome.success else "not SUCCESS"
    echo(f"==> Demo finished in {outcome.duration_s:.1f} s: {verdict}")
    return outcome
