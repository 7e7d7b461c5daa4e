"""The CRDs in crds/ and the chart are generated from the pydantic models and fit the API server's rules."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

from coral_core import instance_status
from coral_operator.api import common, crdgen, system

ROOT = Path(__file__).resolve().parents[3]


def _walk(node: Any, path: str = "") -> list[tuple[str, dict[str, Any]]]:
    found = []
    if isinstance(node, dict):
        found.append((path, node))
        for key, value in node.get("properties", {}).items():
            found.extend(_walk(value, f"{path}.{key}"))
        if isinstance(node.get("items"), dict):
            found.extend(_walk(node["items"], f"{path}[]"))
        if isinstance(node.get("additionalProperties"), dict):
            found.extend(_walk(node["additionalProperties"], f"{path}{{}}"))
    return found


def _schema(kind_file: str) -> dict[str, Any]:
    return crdgen.build_crds()[kind_file]["spec"]["versions"][0]["schema"]["openAPIV3Schema"]


def test_the_committed_crds_are_what_the_models_generate() -> None:
    result = subprocess.run(
        [sys.executable, str(ROOT / "hack" / "generate-crds.py"), "--check"], capture_output=True, text=True
    )
    assert result.returncode == 0, f"crds/ is stale; run python hack/generate-crds.py\n{result.stdout}"


def test_every_spec_field_has_a_description_for_kubectl_explain() -> None:
    for kind_file in crdgen.build_crds():
        spec = _schema(kind_file)["properties"]["spec"]
        # Named fields need a description; list items and map values are explained by their parent.
        missing = [
            path
            for path, node in _walk(spec)
            if path and not path.endswith(("[]", "{}")) and not node.get("description")
        ]
        assert not missing, f"{kind_file}: fields without description: {missing}"


def test_the_schemas_are_structural() -> None:
    forbidden = {"anyOf", "oneOf", "allOf", "$ref", "title", "const", "nullable"}
    for kind_file in crdgen.build_crds():
        for path, node in _walk(_schema(kind_file)):
            assert not forbidden & set(node), f"{kind_file}{path}: {sorted(forbidden & set(node))}"
            if "x-kubernetes-int-or-string" not in node and path:
                assert "type" in node, f"{kind_file}{path} has no type"


def test_the_cel_rules_carry_their_messages() -> None:
    spec = _schema("coral.dev_coralsystems.yaml")["properties"]["spec"]
    messages = {rule["message"] for rule in spec["x-kubernetes-validations"]}
    assert "privileged is allowed only on drivers" in messages
    assert "component names must be unique across drivers, skillsets and executors" in messages
    assert "robots must select with at least one label or expression" in messages
    tree_rules = spec["properties"]["tree"]["x-kubernetes-validations"]
    assert tree_rules[0]["rule"] == "has(self.inline) != has(self.configMapRef)"
    ros_rules = spec["properties"]["ros"]["x-kubernetes-validations"]
    assert "232" in ros_rules[0]["rule"]


def test_object_defaults_spell_out_nested_defaults_so_cel_can_read_them() -> None:
    spec = _schema("coral.dev_coralsystems.yaml")["properties"]["spec"]
    assert spec["properties"]["ros"]["default"]["domainId"] == 0
    assert spec["properties"]["ros"]["default"]["network"] == "Host"


def test_both_kinds_have_status_subresource_short_names_and_a_ready_column() -> None:
    for crd in crdgen.build_crds().values():
        version = crd["spec"]["versions"][0]
        assert version["subresources"] == {"status": {}}
        assert crd["spec"]["names"]["shortNames"]
        assert "coral" in crd["spec"]["names"]["categories"]
        paths = [c["jsonPath"] for c in version["additionalPrinterColumns"]]
        assert any('@.type=="Ready"' in p for p in paths)


def test_the_component_lists_are_keyed_by_name() -> None:
    spec = _schema("coral.dev_coralsystems.yaml")["properties"]["spec"]
    for group in ("drivers", "skillsets", "executors"):
        assert spec["properties"][group]["x-kubernetes-list-type"] == "map"
        assert spec["properties"][group]["x-kubernetes-list-map-keys"] == ["name"]


def test_an_instance_keys_none_of_its_lists_so_its_writes_stay_cheap() -> None:
    """Only the operator and the robot's executor write a CoralInstance, with merge patches that
    replace lists whole; keyed lists would make the API server track every item in managedFields."""
    schema = _schema("coral.dev_coralinstances.yaml")
    keyed: list[str] = []

    def walk(node: object, path: str) -> None:
        if isinstance(node, dict):
            if node.get("x-kubernetes-list-type") == "map":
                keyed.append(path)
            for key, child in node.items():
                walk(child, f"{path}.{key}")

    walk(schema, "")
    assert keyed == []
    conditions = schema["properties"]["status"]["properties"]["conditions"]
    assert conditions["type"] == "array"


def test_a_new_object_of_either_kind_reads_as_pending_until_the_operator_writes_its_status() -> None:
    """The API server fills in `status` from the schema's default on every read of a new object."""
    for kind_file, status_model in (
        ("coral.dev_coralsystems.yaml", system.CoralSystemStatus),
        ("coral.dev_coralinstances.yaml", instance_status.CoralInstanceStatus),
    ):
        default = _schema(kind_file)["properties"]["status"]["default"]
        assert default == common.pending_status()
        conditions = {c.type: c for c in status_model.model_validate(default).conditions}
        assert conditions["Reconciling"].status == "True", "kstatus: InProgress"
        assert conditions["Ready"].status == "Unknown"
        assert "observedGeneration" not in default, "Flux and Argo CD: no generation observed yet"
