"""Every status key the operator and the executor's sink use is a field of the API model.

Status travels as dicts, so a key that is not a field of `CoralInstanceStatus` or
`CoralSystemStatus` (a typo, or a field renamed in the model) is pruned by the API server without
an error: the operator would read nothing and the robot's tree status would vanish. The keys come
from `api.keys` (the models' aliases); these tests check each use without running it, refuse
status keys spelled as strings, and check what the sink and the status builders write against
the models themselves.
"""

from __future__ import annotations

import ast
from pathlib import Path
from typing import Any

import coral_operator
import pytest
from coral.executor import kubernetes_sink as sink
from coral_core import names
from coral_core.instance_status import CoralInstanceStatus
from coral_operator.api import keys
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import CoralSystemSpec, CoralSystemStatus, StartupSpec
from coral_operator.planning import instances, pods
from coral_operator.planning.observed import ObservedInstance, ObservedPod
from coral_operator.status import instance_status, system_status
from operator_specs import NOW, instance_view, robot
from pydantic import BaseModel, ValidationError

PACKAGE = Path(coral_operator.__file__).parent
SINK = Path(sink.__file__)
USERS = sorted(p for p in PACKAGE.rglob("*.py") if p.parent.name != "api")
TABLES = {name: value for name, value in vars(keys).items() if isinstance(value, keys.WireNames)}
# Keys that are also the name of a spec field or of a Kubernetes object's field, so the string
# appears legitimately outside status (a Pod's `spec.nodeName`, `spec.rollout.maxUnavailable`).
SHARED_WITH_SPECS = {"nodeName", "maxUnavailable"}


def _key_uses(path: Path) -> list[tuple[int, str, str]]:
    """(line, table, field) of every `keys.TABLE.field` in the file."""
    uses = []
    for node in ast.walk(ast.parse(path.read_text())):
        if (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Attribute)
            and isinstance(node.value.value, ast.Name)
            and node.value.value.id == "keys"
        ):
            uses.append((node.lineno, node.value.attr, node.attr))
    return uses


def test_every_status_key_used_names_a_field_of_its_model() -> None:
    problems = []
    used = 0
    for path in [*USERS, SINK]:
        for line, table, field in _key_uses(path):
            used += 1
            where = f"{path.name if path == SINK else path.relative_to(PACKAGE)}:{line}"
            if table not in TABLES:
                problems.append(f"{where}: keys.{table} is no model of api.keys")
            elif field not in TABLES[table].model.model_fields:
                problems.append(f"{where}: {TABLES[table].model.__name__} has no field {field!r}")
    assert not problems, problems
    # The scan sees the status builders, so it cannot pass by finding nothing.
    assert used >= 100, used


def test_a_misspelled_key_is_refused_where_it_is_used() -> None:
    assert keys.TREE.root_status == "rootStatus"
    with pytest.raises(AttributeError, match="TreeState has no field 'root'"):
        _ = keys.TREE.root


def _status_aliases() -> set[str]:
    """Wire names of status fields that differ from every plain word (camelCase ones)."""
    aliases = {alias for table in TABLES.values() for alias in table if not alias.islower()}
    return aliases - SHARED_WITH_SPECS


@pytest.mark.parametrize("path", USERS, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_status_key_is_spelled_as_a_string(path: Path) -> None:
    aliases = _status_aliases()
    assert {"rootStatus", "observedGeneration", "lastTransitionTime", "rolledBack"} <= aliases
    spelled = [
        f"line {node.lineno}: {node.value!r}"
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in aliases
    ]
    assert not spelled, f"use api.keys instead: {spelled}"


EXECUTOR_RECORDS: list[dict[str, Any]] = [
    {"event": "waiting", "missing": ["EstimatePose"]},
    {
        "event": "plugins",
        "loaded": [{"component": "slam", "behaviors": ["EstimatePose"]}],
        "conflicts": [{"message": "Two plugins export Move"}],
        "refused": [{"plugin": "old", "reason": "built for humble"}],
    },
    {"event": "condition", "type": "PluginsReady", "status": "True"},
    {
        "event": "status",
        "root_status": "RUNNING",
        "tick_count": 12,
        "active_path": "Main/Seq/Move",
        "last_transition_time": 5.0,
        "last_failure": {"path": "Main/Seq/Check", "message": "no scan", "time": 4.0},
        "conditions": [{"type": "LibraryDegraded", "status": "True", "message": "slam died"}],
    },
    {"event": "condition", "type": "LibraryDegraded", "status": "False"},
    {"event": "error", "message": "lost the skillset"},
    {"event": "finished", "root_status": "FAILURE", "exit_code": 1, "tick_count": 13},
]


def on_the_wire(model: type[BaseModel], status: dict[str, Any]) -> BaseModel:
    """`status` read by wire names only, as the API server's schema reads it (a Python field name
    such as `root_status` would be pruned there, so it is refused here)."""
    return model.model_validate(status, by_alias=True, by_name=False)


def test_every_patch_of_the_sink_is_a_valid_instance_status() -> None:
    patches: list[dict[str, Any]] = []
    status_sink = sink.KubernetesStatusSink(
        patches.append, min_interval_s=0.0, clock=lambda: 0.0, wall=lambda: 0.0, background=False
    )
    for record in EXECUTOR_RECORDS:
        status_sink.emit(record)
    # Every record that changes the summary is one patch; the last `finished` changes nothing.
    assert len(patches) == len(EXECUTOR_RECORDS) - 1
    for patch in patches:
        assert set(patch) == {"status"}
        on_the_wire(CoralInstanceStatus, patch["status"])
    tree = patches[-1]["status"][keys.INSTANCE_STATUS.tree]
    assert tree[keys.TREE.root_status] == "RUNNING" and tree[keys.TREE.tick_count] == 12


def test_the_models_refuse_a_key_they_do_not_have_at_any_depth() -> None:
    """What makes the two tests above and below able to fail."""
    with pytest.raises(ValidationError, match="root"):
        on_the_wire(CoralInstanceStatus, {"tree": {"root": "RUNNING"}})
    with pytest.raises(ValidationError, match="root_status"):
        on_the_wire(CoralInstanceStatus, {"tree": {"root_status": "RUNNING"}})
    with pytest.raises(ValidationError, match="rootStatus"):
        on_the_wire(CoralSystemStatus, {"rootStatus": "RUNNING"})
    on_the_wire(CoralInstanceStatus, {"tree": {"rootStatus": "RUNNING"}})


@pytest.mark.parametrize("online", [True, False], ids=["robot online", "robot away"])
def test_the_status_the_operator_writes_is_a_valid_status(spec_dict: Any, online: bool) -> None:
    summary = sink.summarize(CoralInstanceStatus(), EXECUTOR_RECORDS[3])
    template = instances.build_template(CoralSystemSpec.model_validate(spec_dict()), "t", "p")
    parsed = CoralInstanceSpec.model_validate(instances.build_instance_spec("sys", robot("r1"), template))
    desired = pods.build_pods(spec=parsed, instance="sys-r1", namespace="ns", instance_uid="u")
    # The first component's pod runs; the others wait for it.
    labels = desired[0]["metadata"]["labels"]
    running = ObservedPod(
        name=desired[0]["metadata"]["name"],
        component=labels[names.LABEL_COMPONENT],
        role=labels[names.LABEL_ROLE],
        revision=labels[names.LABEL_REVISION],
        pod_hash=desired[0]["metadata"]["annotations"][names.ANNOTATION_POD_HASH],
        phase="Running",
        ready=True,
        created=NOW,
    )
    view = instance_view(
        parsed,
        desired,
        [running],
        startup=StartupSpec(),
        node=robot("r1", ready=online),
        tree=summary.tree,
        plugins=summary.plugins,
    )
    written = instance_status.build_instance_status(view, old_conditions=[], generation=3, now=NOW)
    on_the_wire(CoralInstanceStatus, written)
    robots = [
        ObservedInstance(
            name=f"sys-r{i}", robot=f"r{i}", spec={}, revision="r1", ready=online, root_status=root
        )
        for i, root in enumerate(["RUNNING", "FAILURE", None])
    ]
    system = system_status.build_system_status(
        system_status.SystemView(matched=3, instances=robots, revision="r1"),
        old_conditions=[],
        generation=2,
        now=NOW,
    )
    on_the_wire(CoralSystemStatus, system)
