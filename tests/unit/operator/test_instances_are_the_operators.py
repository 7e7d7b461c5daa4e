"""Pods are built only for a CoralInstance its CoralSystem made for its robot, within the policy.

Issue 47, item 6: a user who may create CoralInstances but not pods got a privileged, host-network
pod with `/` mounted, and an instance naming another system got a pod running as that system's
executor account. `planning.provenance` decides whether an instance is the operator's; the
reconciler then builds nothing for any other (the last tests here run it).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field, replace
from typing import Any

import pytest
from coral_core import names
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import CoralSystemSpec
from coral_operator.planning import instances, naming, provenance
from coral_operator.planning.observed import ObservedInstance, RobotNode, SystemRecord
from coral_operator.planning.policy import Policy
from coral_operator.planning.revisions import StoredRevision
from operator_specs import BASE_SPEC, robot

SYSTEM = SystemRecord(name="sys", namespace="ns", uid="uid-sys", generation=1, spec=BASE_SPEC, status={})
OWNER = naming.owner_reference(names.API_VERSION, names.SYSTEM_KIND, "sys", "uid-sys")
TEMPLATE = instances.build_template(CoralSystemSpec.model_validate(BASE_SPEC), "tree-cm", "params-cm")
SPEC = instances.build_instance_spec("sys", robot("r1"), TEMPLATE)
STORED = [StoredRevision("sys-" + SPEC["revision"], SPEC["revision"], 1, TEMPLATE)]


def _hostile(spec: dict[str, Any]) -> dict[str, Any]:
    """The spec of the attack: a privileged, host-network driver with the robot's `/` mounted."""
    spec = copy.deepcopy(spec)
    spec["ros"]["network"] = "Host"
    spec["drivers"][0] |= {"privileged": True, "hostPaths": [{"hostPath": "/", "mountPath": "/host"}]}
    return spec


@dataclass
class Case:
    """One instance as observed; `problems` are fragments of the sentences expected (none: ours)."""

    name: str = "sys-r1"
    owners: list[dict[str, Any]] = field(default_factory=lambda: [OWNER])
    spec: dict[str, Any] = field(default_factory=lambda: copy.deepcopy(SPEC))
    system: SystemRecord | None = SYSTEM
    node: RobotNode | None = field(default_factory=lambda: robot("r1"))
    problems: list[str] = field(default_factory=list)


CASES = {
    "serve the instance its system made for its robot": Case(),
    "serve it while its robot's Node is missing (no pod is built, for want of a Node)": Case(node=None),
    "refuse an instance naming a system that does not exist": Case(
        system=None, problems=["spec.system: no CoralSystem sys"]
    ),
    "refuse an instance without a controller": Case(
        owners=[], problems=["metadata.ownerReferences: no controller"]
    ),
    "refuse an owner that is not the controller": Case(
        owners=[{**OWNER, "controller": False}], problems=["metadata.ownerReferences: no controller"]
    ),
    "refuse an instance controlled by another system": Case(
        owners=[naming.owner_reference(names.API_VERSION, names.SYSTEM_KIND, "other", "uid-other")],
        problems=["the controller is CoralSystem other"],
    ),
    "refuse an owner of the system's name from before it was recreated": Case(
        owners=[{**OWNER, "uid": "uid-earlier"}], problems=["(uid uid-earlier)"]
    ),
    "refuse an owner of another kind with the system's name and uid": Case(
        owners=[{**OWNER, "kind": "ConfigMap", "apiVersion": "v1"}], problems=["the controller is ConfigMap"]
    ),
    "refuse an instance at another name than its system gives its robot": Case(
        name="evil", problems=["metadata.name: the instance of robot r1 in sys is sys-r1"]
    ),
    "refuse an instance naming another system (whose account its pods would run as)": Case(
        spec={**copy.deepcopy(SPEC), "system": "other"},
        system=replace(SYSTEM, name="other", uid="uid-other"),
        problems=["the controller is CoralSystem sys", "metadata.name: the instance of robot r1 in other"],
    ),
    "refuse an instance pinned to another robot's Node": Case(
        node=replace(robot("r2"), node_name="r1"), problems=["spec.nodeName: Node r1 is robot r2, not r1"]
    ),
}


@pytest.mark.parametrize("case", CASES.values(), ids=CASES.keys())
def test_ownership(case: Case) -> None:
    spec = CoralInstanceSpec.model_validate(case.spec)
    found = provenance.evaluate_ownership(
        name=case.name, owners=case.owners, spec=spec, system=case.system, node=case.node
    )
    assert len(found) == len(case.problems), found
    for sentence, fragment in zip(found, case.problems, strict=True):
        assert fragment in sentence


REVISION_CASES = {
    "serve the spec of a stored revision": (SPEC, STORED, None),
    "serve it as the API server stores it (defaults, 10.0 as 10)": (
        {**SPEC, "tree": {**SPEC["tree"], "tickRateHz": 10}},
        STORED,
        None,
    ),
    "refuse a privileged, host-network spec with / mounted under the revision's name": (
        _hostile(SPEC),
        STORED,
        "spec: differs from revision",
    ),
    "refuse another executor image under the revision's name": (
        {**SPEC, "executors": [{**SPEC["executors"][0], "image": "someone/else:1"}]},
        STORED,
        "spec: differs from revision",
    ),
    "refuse a revision the system never stored": (
        {**_hostile(SPEC), "revision": "forged"},
        STORED,
        "spec.revision: forged is no stored revision of CoralSystem sys",
    ),
    "refuse any revision of a system whose history is empty": (SPEC, [], "is no stored revision"),
}


@pytest.mark.parametrize(("spec", "stored", "problem"), REVISION_CASES.values(), ids=REVISION_CASES.keys())
def test_revision(spec: dict[str, Any], stored: list[StoredRevision], problem: str | None) -> None:
    found = provenance.evaluate_revision(CoralInstanceSpec.model_validate(spec), stored)
    assert found is None if problem is None else problem in (found or "")


def test_the_policy_holds_for_a_revision_the_system_stored_before_it_was_narrowed() -> None:
    hostile = CoralInstanceSpec.model_validate(_hostile(SPEC))
    denied = provenance.evaluate_instance_policy("ns", hostile, Policy())
    assert any("privileged is not allowed" in d for d in denied)
    assert any("hostPaths[0].hostPath: host path / is outside" in d for d in denied)
    assert any("spec.ros.network" in d for d in denied)
    # What an administrator opened for the namespace, the instance may have.
    opened = _hostile(SPEC)
    opened["drivers"][0]["hostPaths"][0]["hostPath"] = "/data"
    open_policy = Policy(
        privileged_namespaces=frozenset({"ns"}),
        host_network_namespaces=frozenset({"ns"}),
        host_paths=(("ns", "/data"),),
    )
    assert (
        provenance.evaluate_instance_policy("ns", CoralInstanceSpec.model_validate(opened), open_policy) == []
    )


CLAIM_CASES = {
    "a system plans with an instance it controls": ("sys-r1", "uid-sys", True),
    "and with one at a name it gives, which it takes over": ("sys-r1", "", True),
    "and with one left at such a name by an earlier system of its name": ("sys-r1", "uid-earlier", True),
    "but not with one at another name that only names it": ("evil", "", False),
    "nor one at another name controlled by something else": ("evil", "uid-other", False),
}


@pytest.mark.parametrize(("name", "controller", "claimed"), CLAIM_CASES.values(), ids=CLAIM_CASES.keys())
def test_claims(name: str, controller: str, claimed: bool) -> None:
    instance = ObservedInstance(
        name=name, robot="r1", spec=SPEC, revision=SPEC["revision"], controller_uid=controller
    )
    assert provenance.is_claimed_by(instance, "sys", "uid-sys") is claimed
