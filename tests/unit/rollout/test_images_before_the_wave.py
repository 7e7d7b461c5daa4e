"""Images before the wave (`spec.rollout.prePull`): which robots have the images, and when a wave may start.

The pure parts: `planning.prepull` (a robot's pull from its pre-pull pod, the gate, the pods to
create and delete) and the gate inside the whole rollout chain (`planning.rollout.plan_rollout`).
Rows are named as sentences.
"""

from __future__ import annotations

import copy
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest
import yaml
from coral_core import names
from coral_operator.api.rollout import PrePullStatus, PullFailure, RolloutStatus
from coral_operator.api.system import PrePullSpec, RolloutSpec
from coral_operator.kube import observing
from coral_operator.planning import prepull, system_pass
from coral_operator.planning.observed import ObservedInstance, ObservedPod
from coral_operator.planning.policy import Policy
from coral_operator.planning.prepull import PullingRobot
from coral_operator.planning.pull_state import PULL_COMMAND, PULL_ROLE, Pull, PullState, read_pull
from coral_operator.planning.rollout import RobotView, RolloutRequest, plan_rollout
from coral_operator.rollout_control import describe
from fixtures.system_passes import fleet_robots, plan_system_pass

NOW = datetime(2026, 1, 1, 12, 0, tzinfo=UTC)
OLD, NEW = "old0000000", "new0000000"
PULLED, PULLING, ABSENT = Pull(PullState.PULLED), Pull(PullState.PULLING), Pull()
NO_SPACE = "ErrImagePull: failed to pull: no space left on device"


def row(sentence: str, *values: Any) -> Any:
    return pytest.param(*values, id=sentence)


def pod(revision: str = NEW, phase: str = "Pending", role: str = PULL_ROLE, **fields: Any) -> ObservedPod:
    return ObservedPod(
        name=f"i-{role}-{revision}",
        component=role,
        role=role,
        revision=revision,
        pod_hash="",
        phase=phase,
        ready=False,
        created=NOW,
        **fields,
    )


@pytest.mark.parametrize(
    ("pods", "state", "message"),
    [
        row("no pre-pull pod means nothing is pulled yet", [], PullState.ABSENT, ""),
        row(
            "a component pod is no pre-pull pod",
            [pod(role="skillset", phase="Running")],
            PullState.ABSENT,
            "",
        ),
        row(
            "a pre-pull pod of another revision does not count", [pod(OLD, "Succeeded")], PullState.ABSENT, ""
        ),
        row("a pending pod is pulling", [pod()], PullState.PULLING, ""),
        row("a running pod has containers left to pull", [pod(phase="Running")], PullState.PULLING, ""),
        row("a pod whose containers all ran has every image", [pod(phase="Succeeded")], PullState.PULLED, ""),
        row("an image without the no-op command still arrived", [pod(phase="Failed")], PullState.PULLED, ""),
        row(
            "the kubelet's pull failure is kept word for word",
            [pod(image_problem=NO_SPACE)],
            PullState.FAILED,
            NO_SPACE,
        ),
        row(
            "a robot that cannot run the pod failed",
            [pod(unschedulable="OutOfmemory: Node didn't have enough")],
            PullState.FAILED,
            "OutOfmemory: Node didn't have enough",
        ),
        row("a pod being deleted is gone", [pod(phase="Succeeded", deleting=True)], PullState.ABSENT, ""),
    ],
)
def test_a_robots_pull_is_read_from_its_pre_pull_pod(
    pods: list[ObservedPod], state: PullState, message: str
) -> None:
    assert read_pull(pods, NEW) == Pull(state, message)


def gate(
    pulls: list[Pull],
    *,
    when: str = "BeforeRollout",
    previous: PrePullStatus | None = None,
    now: datetime = NOW,
    offline: frozenset[int] = frozenset(),
) -> prepull.PullGate:
    robots = [PullingRobot(f"r{i}", i not in offline, pull) for i, pull in enumerate(pulls)]
    return prepull.check_pre_pull(
        spec=PrePullSpec(when=when, deadline_seconds=300),
        robots=robots,
        target=NEW,
        previous=previous,
        now=now,
    )


@pytest.mark.parametrize(
    ("pulls", "offline", "held", "may_move", "reason"),
    [
        row(
            "nobody moves while one robot still pulls",
            [PULLED, PULLING],
            frozenset(),
            True,
            {"r0"},
            "WaitingForImages",
        ),
        row(
            "nobody moves before the pods even exist",
            [ABSENT, ABSENT],
            frozenset(),
            True,
            set(),
            "WaitingForImages",
        ),
        row(
            "the wave starts once every robot pulled",
            [PULLED, PULLED],
            frozenset(),
            False,
            {"r0", "r1"},
            "Released",
        ),
        row(
            "a failed pull does not hold the others, and its robot does not move",
            [PULLED, Pull(PullState.FAILED, NO_SPACE)],
            frozenset(),
            False,
            {"r0"},
            "Released",
        ),
        row(
            "an offline robot is not waited for (offlineRobots decides)",
            [PULLED, ABSENT],
            frozenset({1}),
            False,
            {"r0"},
            "Released",
        ),
    ],
)
def test_before_the_rollout_no_robot_moves_until_every_robot_to_move_has_its_images(
    pulls: list[Pull], offline: frozenset[int], held: bool, may_move: set[str], reason: str
) -> None:
    decided = gate(pulls, offline=offline)
    assert (decided.held, set(decided.may_move), decided.reason) == (held, may_move, reason)


def test_each_wave_moves_the_robots_whose_images_are_there() -> None:
    decided = gate([PULLED, PULLING, ABSENT], when="BeforeEachWave")
    assert not decided.held
    assert decided.may_move == {"r0"}


def test_the_deadline_releases_the_wave_and_counts_robots_still_pulling_as_failed() -> None:
    first = gate([PULLED, PULLING])
    assert first.held and first.wake_at == NOW + timedelta(seconds=300)
    late = gate([PULLED, PULLING], previous=first.status, now=NOW + timedelta(seconds=301))
    assert not late.held and late.may_move == {"r0"}
    assert (late.status.pulled, late.status.pulling, late.status.failed) == (1, 0, 1)
    assert late.status.failures[0].robot == "r1"
    assert "after 300 s" in late.status.failures[0].message
    assert late.status.started == first.status.started


def test_a_released_wave_stays_released_for_robots_that_come_back_later() -> None:
    released = gate([PULLED])
    assert released.status.released
    back = gate([PULLED, ABSENT], previous=released.status)
    assert not back.held and back.may_move == {"r0"}


def test_a_new_revision_starts_its_own_clock_and_gate() -> None:
    other = PrePullStatus(revision=OLD, released=True, started="2025-01-01T00:00:00Z")
    decided = gate([PULLING], previous=other)
    assert decided.held and decided.status.started == "2026-01-01T12:00:00Z"


def fleet(count: int, pulls: dict[int, Pull] | None = None) -> list[RobotView]:
    return [
        RobotView(robot=f"r{i}", revision=OLD, ready=True, pulls={NEW: (pulls or {}).get(i, ABSENT)})
        for i in range(count)
    ]


def decide(robots: list[RobotView], previous: RolloutStatus | None = None, **policy: Any) -> Any:
    return plan_rollout(
        RolloutRequest(
            desired=NEW,
            history=(OLD, NEW),
            robots=robots,
            policy=RolloutSpec.model_validate(policy),
            previous=previous,
            now=NOW,
        )
    )


def test_a_rollout_with_pre_pull_moves_nobody_until_every_image_is_present() -> None:
    pre_pull = {"when": "BeforeRollout"}
    start = decide(fleet(4), maxUnavailable="100%", prePull=pre_pull)
    assert start.moves == {}
    assert start.pulls == ["r0", "r1", "r2", "r3"]
    assert start.status.pre_pull.pulling == 4
    assert (
        "images on 0 of 4 robots to move, 4 pulling, no robot moves before they are pulled"
        in start.status.message
    )
    partly = decide(
        fleet(4, {0: PULLED, 1: PULLED, 2: PULLED}), start.status, maxUnavailable="100%", prePull=pre_pull
    )
    assert partly.moves == {}
    failed = Pull(PullState.FAILED, NO_SPACE)
    done = decide(
        fleet(4, {0: PULLED, 1: PULLED, 2: PULLED, 3: failed}),
        partly.status,
        maxUnavailable="100%",
        prePull=pre_pull,
    )
    assert sorted(done.moves) == ["r0", "r1", "r2"]
    assert done.status.pre_pull.failures[0].message == NO_SPACE
    assert [e.reason for e in done.events if e.warning] == ["ImagePrePullFailed"]
    assert NO_SPACE in next(e.message for e in done.events if e.reason == "ImagePrePullFailed")


def test_pre_pulled_robots_still_move_within_max_unavailable() -> None:
    decided = decide(fleet(4, {i: PULLED for i in range(4)}), maxUnavailable=1, prePull={})
    assert len(decided.moves) == 1


def test_without_pre_pull_the_rollout_pulls_nothing_and_says_nothing_of_images() -> None:
    decided = decide(fleet(4), maxUnavailable="100%")
    assert len(decided.moves) == 4
    assert decided.pulls == []
    assert decided.status.pre_pull is None
    assert "images" not in decided.status.message


def target(instance: str, images: tuple[str, ...] = ("reg/a:2", "reg/b:2")) -> prepull.PullTarget:
    return prepull.PullTarget(
        instance=instance,
        instance_uid="uid-" + instance,
        node_name="node-" + instance,
        robot=instance,
        images=images,
    )


def test_pre_pull_pods_are_made_for_robots_to_move_and_removed_everywhere_else() -> None:
    writes = prepull.plan_pulls(
        system="demo",
        namespace="ns",
        target=NEW,
        wanted=[target("a"), target("b")],
        pods={
            "a": [pod(NEW)],
            "b": [pod(OLD, "Succeeded")],
            "c": [pod(NEW, "Succeeded"), pod(role="executor")],
        },
    )
    assert [m["metadata"]["labels"][names.LABEL_INSTANCE] for m in writes.create] == ["b"]
    assert sorted(writes.delete) == [f"i-prepull-{NEW}", f"i-prepull-{OLD}"]


def test_a_pre_pull_pod_makes_the_robots_own_kubelet_pull_each_image_and_end() -> None:
    manifest = prepull.build_pull_pod(system="demo", namespace="ns", target=NEW, want=target("a"))
    spec = manifest["spec"]
    assert spec["nodeName"] == "node-a"
    assert spec["restartPolicy"] == "Never"
    assert [c["image"] for c in spec["containers"]] == ["reg/a:2", "reg/b:2"]
    assert all(c["command"] == list(PULL_COMMAND) for c in spec["containers"])
    assert manifest["metadata"]["ownerReferences"][0]["uid"] == "uid-a"
    labels = manifest["metadata"]["labels"]
    assert (labels[names.LABEL_ROLE], labels[names.LABEL_REVISION]) == (PULL_ROLE, NEW)


def test_a_revisions_images_are_listed_once_each_in_startup_order() -> None:
    template = {
        "drivers": [{"image": "reg/d:1"}],
        "skillsets": [{"image": "reg/s:1"}, {"image": "reg/d:1"}],
        "executors": [{"image": "reg/e:1"}],
    }
    assert prepull.revision_images(template) == ("reg/d:1", "reg/s:1", "reg/e:1")


def test_rollout_status_shows_the_pull_progress_and_each_failure_with_the_kubelets_words() -> None:
    status = RolloutStatus(
        revision=NEW,
        pre_pull=PrePullStatus(
            revision=NEW,
            robots=5,
            pulled=3,
            pulling=1,
            failed=1,
            failures=[PullFailure(robot="r4", message=NO_SPACE)],
        ),
    )
    text = describe({"metadata": {"name": "patrol"}, "status": {"rollout": status.to_wire()}})
    assert (
        f"pre-pull of revision {NEW}: images on 3 of 5 robots to move, 1 pulling, 1 failed (r4), "
        "no robot moves before they are pulled"
    ) in text
    assert f"pull failed on r4: {NO_SPACE}" in text


MISSION = yaml.safe_load(
    (Path(__file__).resolve().parents[3] / "examples" / "fleet" / "mission.yaml").read_text()
)
POLICY = Policy(host_network_namespaces=frozenset({"*"}), host_paths=(("*", "/var/lib/coral/bags"),))


def system_pass_of(
    spec: dict[str, Any], instances: list[ObservedInstance], pods: Any
) -> system_pass.SystemPlan:
    record = observing.system_record(
        {"metadata": {"name": "fleet", "namespace": "ns", "uid": "u-fleet"}, "spec": spec}
    )
    return plan_system_pass(
        record, spec, fleet_robots(3), now=NOW, policy=POLICY, instances=instances, pods=pods
    )


def deployed_fleet(pre_pull: dict[str, Any] | None) -> tuple[dict[str, Any], list[ObservedInstance]]:
    """Three robots running the mission's first revision, and a second revision with a new executor image."""
    spec = copy.deepcopy(MISSION["spec"])
    spec["robots"] = {"matchLabels": {"fleet": "f"}}
    spec["rollout"] = {"maxUnavailable": "100%", **({"prePull": pre_pull} if pre_pull is not None else {})}
    first = system_pass_of(spec, [], None)
    running = [
        ObservedInstance(
            name=m["metadata"]["name"],
            robot=m["spec"]["robot"],
            spec=m["spec"],
            revision=m["spec"]["revision"],
            ready=True,
            uid=f"u-{m['spec']['robot']}",
            controller_uid="u-fleet",
        )
        for m in first.changes.create
    ]
    spec["executors"][0]["image"] += "-2"
    return spec, running


def test_a_system_pass_with_pre_pull_creates_pull_pods_and_moves_nobody_yet() -> None:
    spec, running = deployed_fleet({"when": "BeforeRollout"})
    plan = system_pass_of(spec, running, {})
    assert plan.rollout is not None
    assert plan.rollout.moves == {}
    assert {m["spec"]["revision"] for m in plan.changes.update} <= {running[0].revision}
    made = plan.rollout.pulls.create
    assert sorted(m["spec"]["nodeName"] for m in made) == ["n0", "n1", "n2"]
    assert spec["executors"][0]["image"] in made[0]["spec"]["containers"][-1]["image"]
    assert plan.rollout.status.pre_pull is not None and plan.rollout.status.pre_pull.pulling == 3


def test_without_pre_pull_a_system_pass_reads_no_pod_and_writes_none() -> None:
    spec, running = deployed_fleet(None)
    plan = system_pass_of(spec, running, None)
    assert plan.rollout is not None
    assert sorted(plan.rollout.moves) == ["r0", "r1", "r2"]
    assert plan.rollout.pulls == prepull.PullWrites()
