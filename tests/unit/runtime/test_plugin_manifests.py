"""Manifest schema: parse errors name the file and field; the Groot2 palette lists every port."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from coral.plugins import manifest as manifests
from coral_core.bt import treenodesmodel

from .plugin_builders import greeter_plugin


def test_a_manifest_that_is_not_json_is_refused_with_file_and_line() -> None:
    with pytest.raises(manifests.ManifestError, match=r"^m\.json:3: invalid JSON"):
        manifests.parse_manifest('{\n "schema_version": 1,\n oops\n}', "m.json")


def test_a_manifest_without_a_schema_version_names_the_field() -> None:
    with pytest.raises(manifests.ManifestError, match="field 'schema_version'"):
        manifests.parse_manifest("{}", "m.json")


def test_a_bad_behavior_kind_names_the_field_path(tmp_path: Path) -> None:
    folder = greeter_plugin(tmp_path, "alpha", "Hello", "hi")
    raw = json.loads((folder / "manifest.json").read_text())
    raw["behaviors"][0]["kind"] = "gadget"
    with pytest.raises(manifests.ManifestError, match=r"field 'behaviors\.0\.kind'"):
        manifests.parse_manifest(json.dumps(raw), "m.json")


def test_a_component_name_that_is_not_a_node_name_is_refused(tmp_path: Path) -> None:
    folder = greeter_plugin(tmp_path, "alpha", "Hello", "hi")
    raw = json.loads((folder / "manifest.json").read_text())
    raw["component"]["name"] = "bad-name"
    with pytest.raises(manifests.ManifestError, match=r"field 'component\.name'"):
        manifests.parse_manifest(json.dumps(raw), "m.json")


def test_the_manifest_round_trips_through_json(tmp_path: Path) -> None:
    manifest = manifests.read_manifest(greeter_plugin(tmp_path, "alpha", "Hello", "hi"))
    again = manifests.parse_manifest(manifest.to_json(), "again.json")
    assert again == manifest
    assert again.content_hash() == manifest.content_hash()


def test_the_tree_nodes_model_lists_behaviors_with_their_ports(tmp_path: Path) -> None:
    manifest = manifests.read_manifest(greeter_plugin(tmp_path, "alpha", "Hello", "hi"))
    manifest.behaviors.append(
        manifests.BehaviorEntry.model_validate(
            {
                "id": "IsReady",
                "kind": "condition",
                "module": "behaviors",
                "class": "IsReady",
                "ports": [{"name": "limit", "type": "int", "default": "3", "description": "Upper bound"}],
            }
        )
    )
    root = ET.fromstring(treenodesmodel.build_tree_nodes_model(manifests.palette_behaviors([manifest])))
    assert root.get("BTCPP_format") == "4"
    model = root.find("TreeNodesModel")
    assert model is not None
    assert [(child.tag, child.get("ID")) for child in model] == [
        ("Action", "Hello"),
        ("Condition", "IsReady"),
    ]
    port = model.find("Condition/input_port")
    assert port is not None
    assert (port.get("name"), port.get("type"), port.get("default"), port.text) == (
        "limit",
        "int",
        "3",
        "Upper bound",
    )
    assert model.find("Action/output_port").get("name") == "greeting"  # type: ignore[union-attr]


# Manifest spelling -> what BT.CPP's writeTreeNodesModelXML prints (BT::demangle of the C++ type).
BT_CPP_TYPE_NAMES = {
    "string": "std::string",
    "std::string": "std::string",
    "any": "BT::AnyTypeAllowed",
    "": "BT::AnyTypeAllowed",
    "int": "int",
    "double": "double",
    "bool": "bool",
    "unsigned int": "unsigned int",
    "NodeStatus": "BT::NodeStatus",
    "list[double]": "std::vector<double>",
    "list:string": "std::vector<std::string>",
    "geometry_msgs::msg::Pose": "geometry_msgs::msg::Pose",
}


@pytest.mark.parametrize(("declared", "written"), BT_CPP_TYPE_NAMES.items())
def test_port_types_are_written_with_bt_cpp_names(declared: str, written: str) -> None:
    assert treenodesmodel.cpp_type_name(declared) == written
