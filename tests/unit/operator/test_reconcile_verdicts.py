"""One reconcile pass per verdict, for both kinds, without a cluster.

The reconcilers run as the operator runs them, on indexes filled with records and against an
in-memory writer (`fake_writer.FakeWriter`, which keeps what was written and can refuse a write
as an admission controller would). Each test names the verdict a user would read with `kubectl get`.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from coral_core import names
from coral_operator.api import common
from coral_operator.api.system import CoralSystemSpec
from coral_operator.kube import observing
from coral_operator.planning import instances, naming, revisions
from coral_operator.planning.observed import InstanceRecord, ObservedInstance, RobotNode, SystemRecord
from coral_operator.planning.pods import PodSettings
from coral_operator.planning.policy import Policy
from coral_operator.planning.revisions import StoredRevision
from coral_operator.planning.status_pacing import PROGRESS_INTERVAL_S, progress_interval
from coral_operator.reconcile.indexes import ALL_ROBOTS, Indexes, instance_named, instances_of_system
from coral_operator.reconcile.instances import InstanceReconciler
from coral_operator.reconcile.memory import Memory
from coral_operator.reconcile.systems import FILES_AT_ONCE, SystemReconciler
from fake_writer import FakeWriter
from operator_specs import BASE_SPEC, NOW, robot

NS = "ns"


@pytest.fixture
def kube() -> FakeWriter:
    return FakeWriter()


class Harness:
    """Both reconcilers over hand-filled indexes; `requeued` and `events` record what they asked for."""

    def __init__(self, kube: FakeWriter) -> None:
        self.kube = kube
        self.memory = Memory(clock=lambda: self.seconds)
        self.seconds = 1000.0
        self.indexes = Indexes()
        self.tables: dict[str, dict[Any, list[Any]]] = {
            name: {} for name in ("robot_nodes", "coral_pods", "coral_systems", "coral_instances")
        }
        self.indexes.attach(**self.tables)
        self.requeued: list[tuple[tuple[str, str], float]] = []
        self.events: list[tuple[str, str, str, str]] = []
        common: dict[str, Any] = {
            "memory": self.memory,
            "indexes": self.indexes,
            "writer": kube,
            "post": lambda ref, kind, reason, message: self.events.append(
                (ref["metadata"]["name"], kind, reason, message)
            ),
            "requeue": lambda key, delay: self.requeued.append((key, delay)),
            "clock": lambda: NOW,
        }
        self.woken: list[tuple[str, str]] = []
        policy = Policy(host_network_namespaces=frozenset({NS}))
        self.instances = InstanceReconciler(
            **common, wake_system=self.woken.append, pod_settings=PodSettings(policy=policy)
        )
        self.handed_over: list[tuple[str, str]] = []
        self.systems = SystemReconciler(
            **common,
            policy=policy,
            pool=_Inline(),
            wake_instance=self.handed_over.append,
        )

    def add_robot(self, node: RobotNode) -> None:
        self.tables["robot_nodes"].setdefault(ALL_ROBOTS, []).append(node)
        self.tables["robot_nodes"][("node", node.node_name)] = [node]

    # --- instances ---------------------------------------------------------------------------

    def instance(
        self,
        spec: dict[str, Any],
        name: str = "sys-r1",
        generation: int = 1,
        *,
        by_hand: tuple[dict[str, Any], ...] | None = None,
    ) -> None:
        """The instance as its system made it: owned by the system, at a revision it stored; or,
        with `by_hand` (its owner references), as someone wrote it, its spec stored nowhere."""
        status = self.kube.status.get(name, {})
        system = spec.get("system", "sys")
        if (NS, system) not in self.tables["coral_systems"] and by_hand is None:
            self.system(BASE_SPEC, system)
        if by_hand is None and spec.get("revision") not in {
            stored.revision for stored in self.kube.revisions
        }:
            template = revisions.template_of_instance(spec)
            number = len(self.kube.revisions) + 1
            self.kube.revisions.append(
                StoredRevision(f"{system}-{spec.get('revision')}", spec.get("revision", ""), number, template)
            )
        owner = naming.owner_reference(names.API_VERSION, names.SYSTEM_KIND, system, "uid-" + system)
        self.tables["coral_instances"][instance_named(NS, name)] = [
            InstanceRecord(
                name=name,
                namespace=NS,
                uid="uid-" + name,
                generation=generation,
                spec=spec,
                status=copy.deepcopy(status),
                resource_version=str(self.kube.version),
                owners=(owner,) if by_hand is None else by_hand,
            )
        ]
        # One watch event updates every key of an instance, so its system's view of it is at the
        # same resourceVersion (what it shows of the status stays as `instances_are` set it).
        views = self.tables["coral_instances"].get(instances_of_system(NS, system), [])
        self.tables["coral_instances"][instances_of_system(NS, system)] = [
            dataclasses.replace(view, resource_version=str(self.kube.version))
            if isinstance(view, ObservedInstance) and view.name == name
            else view
            for view in views
        ]

    def pods_are(self, ready: set[str], **overrides: dict[str, Any]) -> None:
        """Every created pod as the kubelet reports it: Running, Ready when its component is in `ready`."""
        bodies = []
        for name, manifest in self.kube.pods.items():
            component = manifest["metadata"]["labels"][names.LABEL_COMPONENT]
            status = {
                "phase": "Running",
                "conditions": [{"type": "Ready", "status": "True" if component in ready else "False"}],
                "containerStatuses": [{"name": component, "ready": component in ready, "restartCount": 0}],
                **overrides.get(component, {}),
            }
            body = {"metadata": {**manifest["metadata"], "creationTimestamp": "2026-01-01T11:59:55Z"}}
            bodies.append({**body, "spec": manifest["spec"], "status": status})
            assert name == manifest["metadata"]["name"]
        self.tables["coral_pods"][(NS, "sys-r1")] = [observing.observed_pods(body) for body in bodies]

    def pass_instance(
        self, spec: dict[str, Any], name: str = "sys-r1", generation: int = 1
    ) -> dict[str, Any]:
        self.instance(spec, name, generation)
        self.instances.reconcile((NS, name))
        return self.kube.status.get(name, {})

    def start_every_component(self, spec: dict[str, Any]) -> dict[str, Any]:
        """Robot r1's start, one pass per stage as each stage's pods become Ready (drivers, then
        skillsets, then the executor); returns the status of the last pass."""
        status: dict[str, Any] = {}
        for ready in (set(), {"lidar"}, {"lidar", "slam"}, {"lidar", "slam", "executor"}):
            self.pods_are(ready=ready)
            status = self.pass_instance(spec)
        return status

    # --- systems -----------------------------------------------------------------------------

    def system(self, spec: dict[str, Any], name: str = "sys") -> None:
        self.tables["coral_systems"][(NS, name)] = [
            SystemRecord(
                name=name,
                namespace=NS,
                uid="uid-" + name,
                generation=1,
                spec=spec,
                status=copy.deepcopy(self.kube.status.get(name, {})),
                resource_version=str(self.kube.version),
            )
        ]

    def instances_are(self, ready: bool) -> None:
        """The instances the system created, as the index holds them, Ready or not."""
        bodies = []
        for manifest in self.kube.instances.values():
            conditions = [{"type": "Ready", "status": "True" if ready else "False", "observedGeneration": 1}]
            bodies.append(
                {
                    "metadata": {
                        **manifest["metadata"],
                        "generation": 1,
                        "uid": "uid-" + manifest["metadata"]["name"],
                        "resourceVersion": str(self.kube.version),  # noqa: SLF001
                    },
                    "spec": manifest["spec"],
                    "status": {"conditions": conditions, "robot": {"reachable": True, "nodeReady": True}},
                }
            )
        self.tables["coral_instances"][instances_of_system(NS, "sys")] = [
            observing.observed_instance(body) for body in bodies
        ]

    def pass_system(self, spec: dict[str, Any], name: str = "sys") -> dict[str, Any]:
        self.system(spec, name)
        self.systems.reconcile((NS, name))
        return self.kube.status.get(name, {})


class _Inline:
    """Runs the system's parallel writes in order, so the recorded writes are deterministic."""

    def map(self, call: Callable[[Any], Any], items: list[Any]) -> Iterator[Any]:
        return iter([call(item) for item in items])


@pytest.fixture
def harness(kube: FakeWriter) -> Harness:
    made = Harness(kube)
    made.add_robot(robot("r1"))
    return made


def _conditions(status: dict[str, Any]) -> dict[str, tuple[str, str]]:
    return {c["type"]: (c["status"], c["reason"]) for c in status.get("conditions") or []}


def _instance_spec() -> dict[str, Any]:
    """The spec a system of BASE_SPEC gives robot r1."""
    template = instances.build_template(CoralSystemSpec.model_validate(BASE_SPEC), "tree-cm", "params-cm")
    return instances.build_instance_spec("sys", robot("r1"), template)


# --- CoralInstance verdicts ------------------------------------------------------------------------


def test_instance_reconciling_a_new_robot_starts_its_drivers_and_writes_status_once(harness: Harness) -> None:
    spec = _instance_spec()
    status = harness.pass_instance(spec)
    assert harness.kube.of("create pod") == ["sys-r1-lidar"]
    assert _conditions(status)["Ready"][0] == "False"
    assert _conditions(status)["Reconciling"] == ("True", "Progressing")
    assert _conditions(status)["Stalled"][0] == "False"
    harness.pods_are(ready=set())
    harness.pass_instance(spec)
    assert harness.kube.of("patch status") == ["sys-r1"], "nothing a verdict reads changed"


def test_instance_pass_before_the_index_caught_up_makes_no_write_twice(harness: Harness) -> None:
    spec = _instance_spec()
    harness.pass_instance(spec)
    harness.pass_instance(spec)  # the index does not show the driver's pod yet
    assert harness.kube.of("create pod") == ["sys-r1-lidar"], "created once, as the watch will show"
    harness.pods_are(ready=set())
    harness.pass_instance(spec)  # the watch shows the pod
    harness.tables["coral_pods"][(NS, "sys-r1")] = []  # and then someone deletes it
    harness.pass_instance(spec)
    assert harness.kube.of("create pod") == ["sys-r1-lidar"] * 2, "a pod seen and gone is made again"


def test_instance_progress_without_a_verdict_change_waits_instead_of_writing(harness: Harness) -> None:
    spec = _instance_spec()
    harness.pass_instance(spec)
    harness.pods_are(ready={"lidar"})
    harness.pass_instance(spec)
    assert harness.kube.of("create pod") == ["sys-r1-lidar", "sys-r1-slam"]
    assert harness.kube.of("patch status") == ["sys-r1"], "a stage's progress is not a verdict"
    assert harness.requeued and harness.requeued[-1][0] == (NS, "sys-r1"), "it goes out later"


def test_instance_ready_once_every_component_is_ready(harness: Harness) -> None:
    spec = _instance_spec()
    status = harness.start_every_component(spec)
    assert _conditions(status)["Ready"] == ("True", "Ready")
    assert _conditions(status)["Reconciling"][0] == "False"
    assert [c["ready"] for c in status["components"]] == [True, True, True]
    assert len(harness.kube.of("patch status")) == 2, "one write when it started, one when Ready"
    harness.pass_instance(spec)
    assert len(harness.kube.of("patch status")) == 2, "an unchanged verdict is not written again"


def test_instance_updated_writes_its_status_once_when_ready_at_the_new_generation(harness: Harness) -> None:
    """While the status written for the old generation stands, every reader already sees the
    update in progress: "progressing" is written only if it lasts, and Ready once it is."""
    spec = _instance_spec()
    harness.start_every_component(spec)
    writes = len(harness.kube.of("patch status"))
    updated = copy.deepcopy(spec)
    updated["executors"][0]["image"] = "coral/executor:0.2.0"
    updated["revision"] = "updated"
    harness.pass_instance(updated, generation=2)
    assert len(harness.kube.of("patch status")) == writes, "Ready at generation 1 reads as in progress"
    assert harness.requeued[-1] == ((NS, "sys-r1"), PROGRESS_INTERVAL_S), "unless it lasts"
    harness.seconds += PROGRESS_INTERVAL_S
    status = harness.pass_instance(updated, generation=2)
    assert len(harness.kube.of("patch status")) == writes + 1
    assert status["observedGeneration"] == 2 and _conditions(status)["Reconciling"] == ("True", "Progressing")


def test_instance_of_a_new_robot_writes_one_status_when_it_is_ready_within_the_interval(
    harness: Harness,
) -> None:
    """The API server gives a new instance the CRD's pending status, which every client reads as in
    progress: a robot that starts within PROGRESS_INTERVAL_S costs one status write, its Ready."""
    harness.kube.status["sys-r1"] = common.pending_status()
    spec = _instance_spec()
    for ready in (set(), {"lidar"}, {"lidar", "slam"}):
        harness.pods_are(ready=ready)
        harness.pass_instance(spec)
    assert harness.kube.of("create pod") == ["sys-r1-lidar", "sys-r1-slam", "sys-r1-executor"]
    assert harness.kube.of("patch status") == [], "the pending status says all a reader needs"
    assert harness.requeued[0] == ((NS, "sys-r1"), PROGRESS_INTERVAL_S), "unless the start lasts"
    harness.pods_are(ready={"lidar", "slam", "executor"})
    status = harness.pass_instance(spec)
    assert harness.kube.of("patch status") == ["sys-r1"]
    assert _conditions(status)["Ready"] == ("True", "Ready")
    assert status["observedGeneration"] == 1
    since = {c["lastTransitionTime"] for c in status["conditions"]}
    assert since == {"2026-01-01T12:00:00Z"}, "no transition time is kept from the pending status"


def test_instance_of_a_new_robot_says_how_its_start_goes_once_it_lasts(harness: Harness) -> None:
    harness.kube.status["sys-r1"] = common.pending_status()
    spec = _instance_spec()
    harness.pass_instance(spec)
    harness.pods_are(ready=set())
    harness.seconds += PROGRESS_INTERVAL_S
    status = harness.pass_instance(spec)
    assert harness.kube.of("patch status") == ["sys-r1"]
    assert _conditions(status)["Reconciling"] == ("True", "Progressing")
    assert status["observedGeneration"] == 1
    reconciling = next(c for c in status["conditions"] if c["type"] == "Reconciling")
    assert reconciling["lastTransitionTime"] == "2026-01-01T12:00:00Z", "not the pending status's epoch"


def _progress_written_at(harness: Harness, spec: dict[str, Any], seconds: int) -> list[int]:
    """The seconds at which a start that never ends gets its status written, its progress changing
    every second and never a verdict (the lidar pod restarts every second)."""
    harness.kube.status["sys-r1"] = common.pending_status()
    written_at: list[int] = []
    for second in range(seconds):
        harness.seconds = 1000.0 + second
        restarted = {"name": "lidar", "ready": False, "restartCount": second}
        harness.pods_are(ready=set(), lidar={"containerStatuses": [restarted]})
        before = len(harness.kube.of("patch status"))
        status = harness.pass_instance(spec)
        if len(harness.kube.of("patch status")) > before:
            written_at.append(second)
            assert _conditions(status)["Ready"][0] == "False"
    return written_at


def test_a_long_start_is_reported_less_and_less_often_so_its_writes_stay_bounded(harness: Harness) -> None:
    """The first progress write after 10 s, then 20, 40 and at most 60 s after the one before,
    however long the start lasts."""
    spec = _instance_spec()
    written_at = _progress_written_at(harness, spec, 200)
    assert written_at == [10, 30, 70, 130, 190]
    for ready in ({"lidar"}, {"lidar", "slam"}, {"lidar", "slam", "executor"}):
        harness.pods_are(ready=ready)
        status = harness.pass_instance(spec)
    assert _conditions(status)["Ready"] == ("True", "Ready")
    assert len(harness.kube.of("patch status")) == len(written_at) + 1, "Ready is a verdict: at once"


def test_a_large_fleet_reports_its_robots_starts_less_often_so_its_progress_writes_stay_bounded(
    harness: Harness,
) -> None:
    """A thousand robots starting together would write progress a hundred times a second at 10 s
    apart; a system's robots write it at most 20 times a second between them, so each waits 50 s,
    then 60, and a start within 50 s costs one status write."""
    harness.tables["coral_instances"][instances_of_system(NS, "sys")] = [object()] * 1000
    assert _progress_written_at(harness, _instance_spec(), 200) == [50, 110, 170]


def test_progress_waits_as_long_as_before_in_a_fleet_of_up_to_two_hundred_robots() -> None:
    for robots in (1, 3, 200):
        assert [progress_interval(writes, robots) for writes in range(4)] == [10.0, 20.0, 40.0, 60.0]
    assert [progress_interval(writes, 2000) for writes in range(3)] == [100.0, 100.0, 100.0]


def test_instance_of_a_new_robot_that_is_away_says_so_at_once(harness: Harness) -> None:
    harness.kube.status["sys-r1"] = common.pending_status()
    harness.tables["robot_nodes"][("node", "r1")] = [robot("r1", ready=False)]
    status = harness.pass_instance(_instance_spec())
    assert harness.kube.of("patch status") == ["sys-r1"], "an unreachable robot is a verdict"
    assert _conditions(status)["Stalled"] == ("True", "NodeUnreachable")


def test_instance_stalled_when_a_component_crash_loops(harness: Harness) -> None:
    spec = _instance_spec()
    harness.pass_instance(spec)
    crash = {
        "containerStatuses": [
            {"name": "lidar", "restartCount": 5, "state": {"waiting": {"reason": "CrashLoopBackOff"}}}
        ]
    }
    harness.pods_are(ready=set(), lidar=crash)
    status = harness.pass_instance(spec)
    assert _conditions(status)["Stalled"] == ("True", "ComponentFailed")
    assert ("sys-r1", "Warning", "Stalled") in [e[:3] for e in harness.events]


def test_instance_stalled_with_the_servers_message_when_its_pod_is_refused(harness: Harness) -> None:
    harness.kube.refuse_pods = 'pods "sys-r1-lidar" is forbidden: violates PodSecurity "baseline:latest"'
    spec = _instance_spec()
    status = harness.pass_instance(spec)
    stalled = next(c for c in status["conditions"] if c["type"] == "Stalled")
    assert (stalled["status"], stalled["reason"]) == ("True", "PodRefused")
    assert "violates PodSecurity" in stalled["message"]
    assert any(e[2] == "PodRefused" for e in harness.events), "a Warning Event on the instance"
    assert ((NS, "sys-r1"), 30.0) in harness.requeued, "tried again later: the fix may be outside the spec"


def test_an_image_pull_failure_is_warned_about_and_its_end_told(harness: Harness) -> None:
    """Issue 50: the registry came back and the kubelet's back-off healed the robot minutes later;
    the instance's user, warned of the failure, is told when it ended."""
    spec = _instance_spec()

    def written() -> dict[str, Any]:
        # Progress without a new verdict is written once it lasted PROGRESS_INTERVAL_S.
        harness.pass_instance(spec)
        harness.seconds += PROGRESS_INTERVAL_S
        return harness.pass_instance(spec)

    written()
    refused = 'Back-off pulling image "coral.local/helper:1"'
    init = {"name": "folders-owner", "state": {"waiting": {"reason": "ImagePullBackOff", "message": refused}}}
    harness.pods_are(ready=set(), lidar={"phase": "Pending", "initContainerStatuses": [init]})
    assert _conditions(written())["ComponentsReady"] == ("False", "ImagePullFailed")
    warned = [e for e in harness.events if e[1:3] == ("Warning", "ImagePullFailed")]
    assert len(warned) == 1 and refused in warned[0][3], harness.events
    assert not [e for e in harness.events if e[2] == "Recovered"]
    harness.pods_are(ready={"lidar"})
    assert _conditions(written())["ComponentsReady"] == ("False", "WaitingForSkillsets")
    told = [e for e in harness.events if e[1:3] == ("Normal", "Recovered")]
    assert len(told) == 1 and told[0][3].startswith("No longer ImagePullFailed: Waiting for skillsets"), told
    harness.pods_are(ready={"lidar", "slam"})
    written()
    assert len([e for e in harness.events if e[2] == "Recovered"]) == 1, "told once"


def test_instance_stalled_when_its_spec_is_invalid(harness: Harness) -> None:
    status = harness.pass_instance({"system": "sys", "robot": "r1"})
    assert _conditions(status)["Stalled"] == ("True", "InvalidSpec")
    assert "spec.nodeName" in next(c for c in status["conditions"] if c["type"] == "Stalled")["message"]
    assert harness.kube.of("create pod") == []


def test_instance_reports_an_unreachable_robot_with_when_it_was_last_seen(harness: Harness) -> None:
    spec = _instance_spec()
    harness.tables["robot_nodes"][("node", "r1")] = [robot("r1", ready=False)]
    status = harness.pass_instance(spec)
    assert _conditions(status)["RobotReachable"][0] == "False"
    assert status["robot"]["reachable"] is False
    assert status["robot"]["lastSeen"] == "2026-01-01T11:57:00Z", "read from the robot's Node Lease"


def test_instance_of_a_robot_that_left_stops_executors_first_then_goes(harness: Harness) -> None:
    spec = _instance_spec()
    for ready in (set(), {"lidar"}, {"lidar", "slam"}):
        harness.pods_are(ready=ready)
        harness.pass_instance(spec)
    harness.pods_are(ready={"lidar", "slam", "executor"})
    retiring = {**spec, "retiring": True}
    harness.pass_instance(retiring)
    assert harness.kube.of("delete pod") == ["sys-r1-executor"]
    harness.pods_are(ready=set())
    harness.tables["coral_pods"][(NS, "sys-r1")] = []
    harness.pass_instance(retiring)
    assert harness.kube.of("delete instance") == ["sys-r1"]


def _stalled(status: dict[str, Any]) -> dict[str, Any]:
    return next(c for c in status["conditions"] if c["type"] == "Stalled")


def test_an_instance_written_by_hand_with_a_privileged_spec_gets_no_pod(harness: Harness) -> None:
    """Issue 47, item 6: a user without rights on pods wrote a CoralInstance whose driver is
    privileged, on the host network, with the robot's `/` mounted read-write."""
    harness.system(BASE_SPEC)
    spec = _instance_spec()
    spec["ros"]["network"] = "Host"
    spec["drivers"][0] |= {"privileged": True, "hostPaths": [{"hostPath": "/", "mountPath": "/host"}]}
    harness.instance(spec, by_hand=())
    harness.instances.reconcile((NS, "sys-r1"))
    harness.instances.reconcile((NS, "sys-r1"))
    assert harness.kube.of("create pod") == [] and harness.kube.of("delete pod") == []
    stalled = _stalled(harness.kube.status["sys-r1"])
    assert (stalled["status"], stalled["reason"]) == ("True", "ForeignInstance")
    assert "metadata.ownerReferences: no controller" in stalled["message"]
    assert [e[1:3] for e in harness.events] == [("Warning", "ForeignInstance")], "one Event, not one per pass"


def test_a_hand_edited_spec_under_its_systems_owner_and_name_gets_no_new_pod(harness: Harness) -> None:
    spec = _instance_spec()
    harness.pass_instance(spec)  # as the system made it: its drivers start
    assert harness.kube.of("create pod") == ["sys-r1-lidar"]
    edited = copy.deepcopy(spec)
    edited["drivers"][0]["image"] = "someone/else:1"
    owner = naming.owner_reference(names.API_VERSION, names.SYSTEM_KIND, "sys", "uid-sys")
    harness.instance(edited, generation=2, by_hand=(owner,))
    harness.instances.reconcile((NS, "sys-r1"))
    assert harness.kube.of("create pod") == ["sys-r1-lidar"], "the pod it had is kept, none is built"
    stalled = _stalled(harness.kube.status["sys-r1"])
    assert "spec: differs from revision" in stalled["message"]


def test_an_instance_naming_another_system_gets_no_pod(harness: Harness) -> None:
    harness.system(BASE_SPEC, "other")
    spec = {**_instance_spec(), "system": "other"}
    owner = naming.owner_reference(names.API_VERSION, names.SYSTEM_KIND, "sys", "uid-sys")
    harness.instance(spec, name="other-r1", by_hand=(owner,))
    harness.instances.reconcile((NS, "other-r1"))
    assert harness.kube.of("create pod") == []
    assert "not CoralSystem other" in _stalled(harness.kube.status["other-r1"])["message"]


def test_an_instance_beyond_the_policy_gets_no_pod_even_at_its_systems_revision(harness: Harness) -> None:
    spec = _instance_spec()
    spec["drivers"][0]["privileged"] = True
    harness.pass_instance(spec)
    assert harness.kube.of("create pod") == []
    stalled = _stalled(harness.kube.status["sys-r1"])
    assert stalled["reason"] == "PolicyDenied" and "privileged is not allowed" in stalled["message"]


def test_an_instance_pinned_to_a_node_that_is_no_robot_gets_no_pod(harness: Harness) -> None:
    spec = {**_instance_spec(), "nodeName": "control-plane"}
    status = harness.pass_instance(spec)
    assert harness.kube.of("create pod") == []
    assert _conditions(status)["RobotReachable"] == ("False", "NodeMissing")


def test_a_system_ignores_an_instance_written_by_hand_at_another_name(harness: Harness) -> None:
    harness.pass_system(_spec())
    forged = {
        "metadata": {"name": "evil", "namespace": NS, "uid": "uid-evil", "generation": 1},
        "spec": {**_instance_spec(), "robot": "r1"},
        "status": {"conditions": [{"type": "Stalled", "status": "True", "observedGeneration": 1}]},
    }
    harness.instances_are(ready=True)
    harness.tables["coral_instances"][instances_of_system(NS, "sys")].append(
        observing.observed_instance(forged)
    )
    before = list(harness.kube.writes)
    status = harness.pass_system(_spec())
    assert [
        w for w in harness.kube.writes[len(before) :] if "instance" in w[0] and w[0] != "patch status"
    ] == []
    assert _conditions(status)["Ready"] == ("True", "Ready"), (
        "a forged instance does not count for the system"
    )


# --- CoralSystem verdicts --------------------------------------------------------------------------


def _spec(**changes: Any) -> dict[str, Any]:
    return {**copy.deepcopy(BASE_SPEC), **changes}


def test_system_reconciling_creates_one_instance_per_robot_and_counts_them_in_one_event(
    harness: Harness,
) -> None:
    harness.add_robot(robot("r2"))
    status = harness.pass_system(_spec())
    assert sorted(harness.kube.of("create instance")) == ["sys-r1", "sys-r2"]
    verbs = [verb for verb, _ in harness.kube.writes]
    assert harness.kube.of("apply rbac") == [naming.executor_account_name("sys")]
    assert verbs.index("apply rbac") < verbs.index("create instance"), (
        "the executors' identity exists before any instance whose pods use it"
    )
    assert len(harness.kube.of("create configmap")) == 2, "the validated tree and parameters"
    assert harness.kube.of("create revision") == [""]
    assert _conditions(status)["Reconciling"][0] == "True"
    assert status["robots"]["matched"] == 2
    created = [e for e in harness.events if e[2] == "InstancesCreated"]
    assert len(created) == 1 and created[0][3].startswith("Created 2 CoralInstances")


def test_system_pass_before_the_index_caught_up_creates_no_instance_twice(harness: Harness) -> None:
    harness.add_robot(robot("r2"))
    harness.pass_system(_spec())
    harness.pass_system(_spec())  # the index does not show the new instances yet
    assert sorted(harness.kube.of("create instance")) == ["sys-r1", "sys-r2"], "each made once"
    harness.instances_are(ready=False)
    harness.pass_system(_spec())  # the watch shows them
    harness.tables["coral_instances"][instances_of_system(NS, "sys")] = []  # and then both are deleted
    harness.pass_system(_spec())
    assert sorted(harness.kube.of("create instance")) == ["sys-r1", "sys-r1", "sys-r2", "sys-r2"], (
        "an instance seen and gone is made again"
    )


def test_a_robot_ready_counts_for_its_system_before_the_watch_brings_its_status_back(
    harness: Harness,
) -> None:
    """A rollout's next robots wait on this: the instance's pass wakes its system as it writes the
    verdict, and the system pass reads that write while the index still holds the older status."""
    harness.pass_system(_spec())
    harness.instances_are(ready=False)  # as the watch showed the new instance
    spec = harness.kube.instances["sys-r1"]["spec"]
    harness.start_every_component(spec)
    assert _conditions(harness.kube.status["sys-r1"])["Ready"] == ("True", "Ready")
    assert harness.woken and set(harness.woken) == {(NS, "sys")}
    status = harness.pass_system(_spec())  # the index still shows the instance not ready
    assert status["robots"]["ready"] == 1
    assert _conditions(status)["Ready"] == ("True", "Ready")


def test_a_new_instance_starts_its_robot_once_the_watch_brings_it(harness: Harness) -> None:
    """Its pods name it their owner, and the garbage collector checks an owner it has not seen
    with a GET of it and of its system; its watch sees the instance about when this one does."""
    harness.pass_system(_spec())
    assert harness.kube.of("create instance") == ["sys-r1"]
    assert harness.handed_over == [], "the create's answer starts no pass"
    harness.instances.reconcile((NS, "sys-r1"))  # woken early: the index holds no such instance yet
    assert harness.kube.of("create pod") == []
    harness.pass_instance(harness.kube.instances["sys-r1"]["spec"])  # the watch brings it
    assert harness.kube.of("create pod") == ["sys-r1-lidar"]
    assert _conditions(harness.kube.status["sys-r1"])["Reconciling"] == ("True", "Progressing")


def test_a_moved_instance_starts_its_new_revision_before_the_watch_brings_it(harness: Harness) -> None:
    """Its system pass hands the API server's answer to the instance's pass, which at 1000 robots
    would otherwise wait seconds for the watch, behind every other event of the fleet."""
    harness.pass_system(_spec())
    spec = harness.kube.instances["sys-r1"]["spec"]
    harness.start_every_component(spec)
    harness.instances_are(ready=True)
    env = [{"name": "MISSION", "value": "2"}]
    harness.pass_system(_spec(skillsets=[{"name": "slam", "image": "example/slam:1", "env": env}]))
    assert harness.kube.of("update instance") == ["sys-r1"]
    assert harness.handed_over == [(NS, "sys-r1")]
    harness.instances.reconcile((NS, "sys-r1"))  # the index still holds the old revision
    assert harness.kube.of("delete pod") == ["sys-r1-slam"], "the changed skillset is replaced at once"


def test_an_update_answered_for_an_instance_deleted_since_brings_nothing_back(harness: Harness) -> None:
    answered = observing.instance_record(
        {"metadata": {"name": "sys-r1", "namespace": NS, "uid": "uid-sys-r1", "resourceVersion": "7"}}
    )
    harness.memory.moved.remember(answered)
    harness.instances.reconcile((NS, "sys-r1"))  # the index no longer holds it
    assert harness.kube.writes == []


def test_system_ready_when_every_instance_is_ready(harness: Harness) -> None:
    harness.pass_system(_spec())
    harness.instances_are(ready=True)
    status = harness.pass_system(_spec())
    assert _conditions(status)["Ready"] == ("True", "Ready")
    assert status["robots"]["ready"] == 1
    writes = len(harness.kube.of("patch status"))
    harness.pass_system(_spec())
    assert len(harness.kube.of("patch status")) == writes, "an unchanged status is not written again"


def test_system_first_status_replaces_the_pending_one_with_times_of_its_own(harness: Harness) -> None:
    harness.kube.status["sys"] = common.pending_status()
    status = harness.pass_system(_spec())
    assert _conditions(status)["Reconciling"][0] == "True"
    assert {c["lastTransitionTime"] for c in status["conditions"]} == {"2026-01-01T12:00:00Z"}
    assert not any(c["reason"] == common.PENDING for c in status["conditions"])


def test_system_stalled_when_its_spec_is_invalid(harness: Harness) -> None:
    status = harness.pass_system(_spec(ros={"domainId": 1000}))
    assert _conditions(status)["Stalled"] == ("True", "InvalidSpec")
    assert harness.kube.of("create instance") == []


def test_system_stalled_when_its_tree_is_invalid(harness: Harness) -> None:
    status = harness.pass_system(_spec(tree={"inline": "<root BTCPP_format='4'><BehaviorTree ID='Main'>"}))
    stalled = next(c for c in status["conditions"] if c["type"] == "Stalled")
    assert (stalled["status"], stalled["reason"]) == ("True", "InvalidTree")
    assert "coralsystem/sys spec.tree.inline" in stalled["message"]
    assert harness.kube.of("create instance") == []


def test_system_stalled_when_a_source_config_map_is_missing(harness: Harness) -> None:
    status = harness.pass_system(_spec(tree={"configMapRef": {"name": "trees", "key": "main.xml"}}))
    assert _conditions(status)["Stalled"] == ("True", "ConfigMapNotFound")


def test_a_config_map_its_owners_did_not_mark_as_a_source_is_not_read(harness: Harness) -> None:
    """Issue 47, item 9: the operator reads every ConfigMap, so reading any one a system names
    handed its author ConfigMaps they may not read (a confused deputy), copied into their pods."""
    tree = '<root BTCPP_format="4"><BehaviorTree ID="Main"><AlwaysSuccess/></BehaviorTree></root>'
    harness.kube.config_maps["secrets"] = {"main.xml": tree}
    harness.kube.config_map_labels["secrets"] = {"app": "billing"}
    status = harness.pass_system(_spec(tree={"configMapRef": {"name": "secrets", "key": "main.xml"}}))
    stalled = next(c for c in status["conditions"] if c["type"] == "Stalled")
    assert (stalled["status"], stalled["reason"]) == ("True", "ConfigMapNotASource")
    assert "spec.tree.configMapRef" in stalled["message"] and names.LABEL_SOURCE in stalled["message"]
    assert harness.kube.of("create configmap") == [] and harness.kube.of("create instance") == []


def test_a_refused_read_of_a_source_is_a_status_not_a_retried_error(harness: Harness) -> None:
    # A name the schema admits now; one written before it had a pattern got a 400 retried forever.
    harness.kube.refuse_config_maps = (400, "invalid resource name \"params\": may not contain '%'")
    status = harness.pass_system(_spec(parameters={"configMapRef": {"name": "params", "key": "p.yaml"}}))
    stalled = next(c for c in status["conditions"] if c["type"] == "Stalled")
    assert (stalled["status"], stalled["reason"]) == ("True", "ConfigMapUnreadable")
    assert "spec.parameters.configMapRef" in stalled["message"] and "may not contain" in stalled["message"]


def test_system_stalled_when_the_policy_refuses_it(harness: Harness) -> None:
    privileged = [{"name": "lidar", "image": "example/lidar:1", "privileged": True}]
    status = harness.pass_system(_spec(drivers=privileged))
    assert _conditions(status)["Stalled"] == ("True", "PolicyDenied")
    assert harness.kube.of("create instance") == []


def test_system_not_ready_without_matching_robots(harness: Harness) -> None:
    status = harness.pass_system(_spec(robots={"matchLabels": {"fleet": "nobody"}}))
    assert _conditions(status)["Ready"] == ("False", "NoMatchingRobots")
    assert _conditions(status)["Reconciling"][0] == "False"


def test_system_stalled_with_the_servers_message_when_a_write_is_refused(harness: Harness) -> None:
    harness.kube.refuse_instances = "exceeded quota: coralinstances"
    stalled = _stalled(harness.pass_system(_spec()))
    assert (stalled["status"], stalled["reason"]) == ("True", "ApplyRefused")
    assert "exceeded quota" in stalled["message"]


def test_system_stalled_naming_the_owner_of_an_instance_name_it_needs(harness: Harness) -> None:
    """Issue 47, item 9: a system whose instance name was another's was silently never served."""
    harness.kube.taken_by = "CoralSystem other"
    stalled = _stalled(harness.pass_system(_spec()))
    assert (stalled["status"], stalled["reason"]) == ("True", "NameTaken")
    assert "belongs to CoralSystem other" in stalled["message"]


def test_a_system_with_large_files_gives_its_worker_back_while_every_file_slot_is_taken(
    harness: Harness,
) -> None:
    """Passes waiting for a file slot would hold every worker of the queue, and a small system
    created meanwhile would wait behind them all (200 maximal systems: over a minute). The
    waiting system is passed again when a slot frees."""
    spec = copy.deepcopy(BASE_SPEC)
    spec["parameters"] = {"inline": "driver:\n  ros__parameters:\n    rate: 10\n" + "#" * 100_000 + "\n"}
    for name in ("big", "other"):
        body = {
            "metadata": {"name": name, "namespace": NS, "uid": f"uid-{name}", "generation": 1},
            "spec": spec,
        }
        harness.kube.systems[name] = body
        harness.tables["coral_systems"][(NS, name)] = [observing.system_record(body)]
        assert harness.tables["coral_systems"][(NS, name)][0].files_left_out
    for _ in range(FILES_AT_ONCE - 1):
        assert harness.systems.file_slots.take(("elsewhere", "held"))
    read_system = harness.kube.read_system

    def big_passes_meanwhile(namespace: str, name: str) -> dict[str, Any] | None:
        # While "other" holds the last slot, "big" is passed on another worker.
        if name == "other":
            harness.systems.reconcile((NS, "big"))
            assert "big" not in harness.kube.status and harness.requeued == []
        return read_system(namespace, name)

    harness.kube.read_system = big_passes_meanwhile  # type: ignore[method-assign]
    harness.systems.reconcile((NS, "other"))
    assert harness.kube.status["other"]["observedGeneration"] == 1
    assert harness.requeued == [((NS, "big"), 0.0)]
    harness.systems.reconcile((NS, "big"))
    assert harness.kube.status["big"]["observedGeneration"] == 1
