"""Literal conversion of port values, entry typing and py_trees interoperability."""

from __future__ import annotations

import re

import coral_core.bt as bt
import py_trees
import pytest
from bt_stubs import make_tree
from coral_core.bt.ports import convert_string, normalize_type


@pytest.mark.parametrize(
    ("text", "type_name", "expected"),
    [
        ("42", "int", 42),
        ("0x1F", "int", 0),  # BT.CPP's std::from_chars reads the prefix "0"
        ("2.5", "int", 2),
        ("3 m", "double", 3.0),
        ("2.5", "double", 2.5),
        ("True", "bool", True),
        ("0", "bool", False),
        ("RUNNING", "BT::NodeStatus", bt.Status.RUNNING),
        ("1;2;3", "std::vector<int>", [1, 2, 3]),
        ("0.0;0.6;0.0", "std::vector<double>", [0.0, 0.6, 0.0]),
        ("json:[1,2,3]", "std::vector<int>", [1, 2, 3]),
        ("GREEN", "int", 3),
    ],
)
def test_literal_conversion(text: str, type_name: str, expected: object) -> None:
    assert convert_string(text, normalize_type(type_name), {"GREEN": 3}) == expected


@pytest.mark.parametrize(
    ("text", "type_name"), [("x4", "int"), ("yes", "bool"), ("-", "double"), ("DONE", "NodeStatus")]
)
def test_bad_literals_are_rejected(text: str, type_name: str) -> None:
    with pytest.raises(ValueError, match=re.escape(text)):
        convert_string(text, normalize_type(type_name))


def test_an_entry_keeps_the_type_of_the_first_port_that_created_it() -> None:
    xml = (
        '<root BTCPP_format="4"><BehaviorTree ID="M"><Sequence>'
        '<Repeat num_cycles="{n}"><AlwaysSuccess/></Repeat>'
        '<Precondition if="1" else="{n}"><AlwaysSuccess/></Precondition>'
        "</Sequence></BehaviorTree></root>"
    )
    registry = bt.NodeRegistry.with_builtins()
    with pytest.raises(
        bt.BTLoadError,
        match=r"port \[n\] was initially created with type \[int\] and, later type "
        r"\[NodeStatus\]",
    ):
        bt.build_tree(bt.load_tree_text(xml, registry), registry)


def test_plugin_ports_read_defaults_and_write_outputs() -> None:
    from coral_core.bt.leaves import SyncAction

    class Greet(SyncAction):
        PORTS = [
            bt.PortSpec("who", default="world"),
            bt.PortSpec("times", type="int", default="2"),
            bt.PortSpec("text", bt.PortDirection.OUTPUT, "string"),
        ]

        def tick(self) -> bt.Status:
            self.set_output("text", f"hello {self.get_input('who')}" * self.get_input("times"))
            return bt.Status.SUCCESS

    registry = bt.NodeRegistry.with_builtins()
    registry.register("Greet", Greet)
    xml = '<root BTCPP_format="4"><BehaviorTree ID="M"><Greet text="{out}" times="1"/></BehaviorTree></root>'
    tree = bt.build_tree(bt.load_tree_text(xml, registry), registry, context="ros-node")
    assert tree.tick_exactly_once() == bt.Status.SUCCESS
    assert tree.root_blackboard.get("out") == "hello world"
    assert tree.nodes[0].context == "ros-node"


def test_nodes_are_py_trees_behaviours_that_py_trees_can_display() -> None:
    tree, _ = make_tree('<Sequence name="main"><Q name="a"/></Sequence>', {"a": [bt.Status.RUNNING]})
    tree.tick_exactly_once()
    assert isinstance(tree.root, py_trees.behaviour.Behaviour)
    text = py_trees.display.unicode_tree(tree.root, show_status=True)
    assert "main" in text and "a" in text
    assert tree.root.status == py_trees.common.Status.RUNNING


class _Measure(bt.leaves.SyncAction):
    PORTS = [
        bt.PortSpec("distance", bt.PortDirection.OUTPUT, "double"),
        bt.PortSpec("note", bt.PortDirection.OUTPUT, "string"),
    ]
    written: list[bool] = []

    def tick(self) -> bt.Status:
        type(self).written = [self.set_output("distance", 2.5), self.set_output("note", "measured")]
        return bt.Status.SUCCESS


def test_an_output_the_tree_leaves_unwired_is_skipped_as_bt_cpp_does() -> None:
    registry = bt.NodeRegistry.with_builtins()
    registry.register("Measure", _Measure)
    xml = '<root BTCPP_format="4"><BehaviorTree ID="M"><Measure distance="{d}"/></BehaviorTree></root>'
    tree = bt.build_tree(bt.load_tree_text(xml, registry), registry)
    assert tree.tick_exactly_once() == bt.Status.SUCCESS
    assert _Measure.written == [True, False]
    assert tree.root_blackboard.get("d") == 2.5


class _Typo(bt.leaves.SyncAction):
    PORTS = [bt.PortSpec("distance", bt.PortDirection.OUTPUT, "double")]

    def tick(self) -> bt.Status:
        self.set_output("distnce", 1.0)
        return bt.Status.SUCCESS


def test_writing_a_port_the_node_never_declared_is_an_error_naming_the_node() -> None:
    registry = bt.NodeRegistry.with_builtins()
    registry.register("Typo", _Typo)
    xml = (
        '<root BTCPP_format="4"><BehaviorTree ID="M"><Typo name="typo" distance="{d}"/></BehaviorTree></root>'
    )
    tree = bt.build_tree(bt.load_tree_text(xml, registry), registry)
    with pytest.raises(bt.BTRuntimeError, match=r"typo.*distnce|distnce.*typo"):
        tree.tick_exactly_once()
