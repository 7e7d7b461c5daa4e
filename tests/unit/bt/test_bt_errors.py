"""Bad input never crashes: each problem gives one clear BTError naming file:line or the node path."""

from __future__ import annotations

import threading
from pathlib import Path

import coral_core.bt as bt
import pytest
from coral_core.bt.leaves import SyncAction


def load(xml: str, registry: bt.NodeRegistry | None = None) -> bt.Tree:
    registry = registry or bt.NodeRegistry.with_builtins()
    return bt.build_tree(bt.load_tree_text(xml, registry, filename="t.xml"), registry)


def wrap(body: str, extra: str = "") -> str:
    head = '<root BTCPP_format="4" main_tree_to_execute="M">\n<BehaviorTree ID="M">\n'
    return f"{head}{body}\n</BehaviorTree>{extra}</root>"


@pytest.mark.parametrize(
    ("xml", "message"),
    [
        ("<root><BehaviorTree ID='M'>\n<Sequence>\n</BehaviorTree></root>", r"t.xml:3: malformed XML"),
        ("<tree/>", r"t.xml:1: The XML must have a root node called <root>"),
        (wrap("<Sequence>\n<Frobnicate/>\n</Sequence>"), r"t.xml:4: Node not recognized: Frobnicate"),
        (wrap('<AlwaysSuccess colour="red"/>'), r"t.xml:3: .*port with name \[colour\]"),
        (
            wrap('<Repeat num_cycles="many"><AlwaysSuccess/></Repeat>'),
            r"t.xml:3: .*Can't convert string \[many\] to integer",
        ),
        (wrap('<Script code="x := := 1"/>'), r"t.xml:3: .*invalid script"),
        (wrap('<AlwaysSuccess _skipIf="1 +"/>'), r"t.xml:3: .*invalid script in _skipIf"),
        (wrap("<Inverter/>"), r"t.xml:3: decorator <Inverter> needs exactly 1 child"),
        (wrap("<Sequence/>"), r"t.xml:3: control node <Sequence> needs at least 1"),
        (wrap('<SubTree ID="M"/>'), r"t.xml:3: .*Recursive behavior tree cycle detected"),
        (
            wrap(
                '<SubTree ID="S"/>',
                '<BehaviorTree ID="S"><AlwaysSuccess/></BehaviorTree><TreeNodesModel>'
                '<SubTree ID="S"><input_port name="goal"/></SubTree></TreeNodesModel>',
            ),
            r"t.xml:3: .*mandatory port called \[goal\]",
        ),
        (
            '<root BTCPP_format="4"><BehaviorTree ID="A"><AlwaysSuccess/></BehaviorTree>'
            '<BehaviorTree ID="B"><AlwaysSuccess/></BehaviorTree></root>',
            r"main_tree_to_execute\] was not specified",
        ),
    ],
)
def test_bad_input_gives_one_clear_load_error(xml: str, message: str) -> None:
    with pytest.raises(bt.BTLoadError, match=message):
        load(xml)


def test_include_cycles_are_detected_with_the_chain(tmp_path: Path) -> None:
    (tmp_path / "a.xml").write_text(
        '<root BTCPP_format="4"><include path="sub/b.xml"/>'
        '<BehaviorTree ID="A"><AlwaysSuccess/></BehaviorTree></root>'
    )
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "b.xml").write_text('<root BTCPP_format="4"><include path="../a.xml"/></root>')
    with pytest.raises(bt.BTLoadError, match=r"b.xml:1: include cycle: .*a.xml -> .*b.xml -> .*a.xml"):
        bt.load_tree_file(tmp_path / "a.xml")


def test_includes_resolve_relative_to_the_including_file(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "s.xml").write_text(
        '<root BTCPP_format="4"><BehaviorTree ID="S"><AlwaysFailure/></BehaviorTree></root>'
    )
    (tmp_path / "main.xml").write_text(
        '<root BTCPP_format="4" main_tree_to_execute="M"><include path="sub/s.xml"/>'
        '<BehaviorTree ID="M"><Inverter><SubTree ID="S"/></Inverter></BehaviorTree></root>'
    )
    registry = bt.NodeRegistry.with_builtins()
    tree = bt.build_tree(bt.load_tree_file(tmp_path / "main.xml"), registry)
    assert tree.tick_exactly_once() == bt.Status.SUCCESS


def test_a_script_error_while_ticking_names_the_node_path() -> None:
    tree = load(wrap('<Sequence name="main"><Script name="bad" code="y := missing + 1"/></Sequence>'))
    expected = r"^bad: Error in script .*Variable not found: missing"
    with pytest.raises(bt.BTRuntimeError, match=expected) as info:
        tree.tick_exactly_once()
    assert info.value.node_path == "bad"


def test_a_plugin_exception_is_wrapped_with_the_node_path() -> None:
    class Boom(SyncAction):
        def tick(self) -> bt.Status:
            raise KeyError("gripper")

    registry = bt.NodeRegistry.with_builtins()
    registry.register("Boom", Boom)
    tree = load(wrap('<SubTree ID="S" name="arm"/>', '<BehaviorTree ID="S"><Boom/></BehaviorTree>'), registry)
    with pytest.raises(bt.BTRuntimeError, match=r"^arm/Boom::2: KeyError"):
        tree.tick_exactly_once()


def test_validate_lists_every_static_problem_with_its_line() -> None:
    doc = bt.load_tree_text(
        wrap('<Sequence>\n<Nope/>\n<AlwaysSuccess bad="1"/>\n<Inverter/>\n</Sequence>'), filename="t.xml"
    )
    errors = [str(e) for e in bt.validate_document(doc, bt.NodeRegistry.with_builtins())]
    assert any(e.startswith("t.xml:4:") and "Nope" in e for e in errors)
    assert any(e.startswith("t.xml:5:") and "[bad]" in e for e in errors)
    assert any(e.startswith("t.xml:6:") and "exactly 1 child" in e for e in errors)
    assert doc.missing_node_types(bt.NodeRegistry.with_builtins()) == ["Nope"]


def test_lenient_xml_and_v3_names_load_with_warnings() -> None:
    xml = (
        '<root main_tree_to_execute="M"><!-------- v3 ----------><BehaviorTree ID="M">'
        '<SequenceStar><Script code="a := 1 && 2 < 3"/><RetryUntilSuccesful num_attempts="1">'
        "<AlwaysSuccess/></RetryUntilSuccesful></SequenceStar></BehaviorTree></root>"
    )
    registry = bt.NodeRegistry.with_builtins()
    doc = bt.load_tree_text(xml, registry)
    assert any("SequenceStar" in w for w in doc.warnings)
    tree = bt.build_tree(doc, registry)
    assert tree.tick_once() == bt.Status.SUCCESS
    assert tree.root_blackboard.get("a") == 1.0


def test_transitions_snapshot_rendering_and_thread_safe_wake_up() -> None:
    tree = load(
        wrap(
            '<Sequence name="root"><AlwaysSuccess name="ok"/><Inverter><AlwaysSuccess/></Inverter></Sequence>'
        )
    )
    seen: list[bt.Transition] = []
    tree.add_transition_listener(seen.append)
    assert tree.tick_exactly_once() == bt.Status.FAILURE
    assert (seen[0].path, seen[0].previous, seen[0].status) == ("root", bt.Status.IDLE, bt.Status.RUNNING)
    assert [n.uid for n in tree.snapshot().nodes] == [1, 2, 3, 4]
    assert "✕" not in tree.render_unicode() and "after FAILURE" in tree.render_unicode()
    assert tree.last_tick_duration_s > 0 and tree.tick_count == 1
    threading.Thread(target=tree.wake_up).start()
    assert tree.wait_for_wake_up(5.0)


def test_registry_exports_plugins_as_tree_nodes_model() -> None:
    class Greet(SyncAction):
        PORTS = [bt.PortSpec("name", bt.PortDirection.INPUT, "string", default="world")]

        def tick(self) -> bt.Status:
            return bt.Status.SUCCESS

    registry = bt.NodeRegistry.with_builtins()
    registry.register("Greet", Greet)
    xml = registry.tree_nodes_model_xml()
    assert '<Action ID="Greet">' in xml and 'name="name" type="std::string" default="world"' in xml
    assert "Sequence" not in xml


def test_a_precondition_script_error_is_reported_at_load_with_its_line() -> None:
    with pytest.raises(bt.BTLoadError, match=r"t.xml:3: .*Precondition"):
        load(wrap('<Precondition if="a ==" else="FAILURE"><AlwaysSuccess/></Precondition>'))


def test_transition_timestamps_come_from_the_injected_clock() -> None:
    registry = bt.NodeRegistry.with_builtins()
    doc = bt.load_tree_text(wrap("<AlwaysSuccess/>"), registry)
    tree = bt.build_tree(doc, registry, clock=lambda: 1234.5)
    seen: list[bt.Transition] = []
    tree.add_transition_listener(seen.append)
    tree.tick_exactly_once()
    assert [t.timestamp for t in seen] == [1234.5, 1234.5]  # IDLE->SUCCESS, then reset to IDLE


def test_a_format_3_file_loads_with_its_v3_constructs_converted() -> None:
    xml = """<root BTCPP_format="3" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Sequence>
      <SetBlackboard output_key="goal" value="7"/>
      <SubTree ID="Child" target="goal"/>
      <SubTree ID="Shared" __shared_blackboard="true"/>
      <Parallel success_threshold="2" failure_threshold="1">
        <BlackboardCheckInt value_A="{goal}" value_B="7" return_on_mismatch="FAILURE">
          <AlwaysSuccess/>
        </BlackboardCheckInt>
        <AlwaysSuccess/>
      </Parallel>
    </Sequence>
  </BehaviorTree>
  <BehaviorTree ID="Child"><SetBlackboard output_key="seen" value="{target}"/></BehaviorTree>
  <BehaviorTree ID="Shared"><SetBlackboard output_key="shared" value="yes"/></BehaviorTree>
</root>"""
    registry = bt.NodeRegistry.with_builtins()
    doc = bt.load_tree_text(xml, registry)
    warnings = "\n".join(doc.warnings)
    for expected in ("wrapped in {}", "__shared_blackboard", "success_threshold", "BlackboardCheckInt"):
        assert expected in warnings
    # A host-typed entry: BT.CPP gives a SetBlackboard string nothing to convert it with otherwise.
    tree = bt.build_tree(doc, registry, blackboard={"goal": 0})
    assert tree.tick_exactly_once() == bt.Status.SUCCESS
    assert tree.root_blackboard.get("shared") == "yes"


def test_validation_reports_problems_in_trees_no_subtree_reaches() -> None:
    xml = wrap(
        "<AlwaysSuccess/>",
        '<BehaviorTree ID="Unused">\n<Sequence><AlwaysSuccess typo="1"/><Inverter/></Sequence>'
        "</BehaviorTree>",
    )
    registry = bt.NodeRegistry.with_builtins()
    doc = bt.load_tree_text(xml, registry, filename="t.xml")
    messages = [str(e) for e in bt.validate_document(doc, registry)]
    assert any("t.xml:5" in m and "[typo]" in m for m in messages)
    assert any("t.xml:5" in m and "<Inverter> needs exactly 1 child" in m for m in messages)
    with pytest.raises(bt.BTLoadError, match=r"t.xml:5: .*<Inverter> needs exactly 1 child"):
        bt.build_tree(doc, registry)


def test_a_tree_nested_too_deep_is_refused_before_it_is_built() -> None:
    # Every loader checks the limits the operator applies, so no tree can exhaust Python's stack.
    depth = 1000
    xml = (
        '<root BTCPP_format="4"><BehaviorTree ID="M">'
        + "<Inverter>" * depth
        + "<AlwaysSuccess/>"
        + "</Inverter>" * depth
        + "</BehaviorTree></root>"
    )
    with pytest.raises(bt.BTLoadError, match="nest 1003 levels deep; the limit is 128"):
        bt.load_tree_text(xml, bt.NodeRegistry.with_builtins())


def test_subtrees_nested_too_deep_are_refused_with_their_chain() -> None:
    trees = "".join(
        f'<BehaviorTree ID="T{i}"><Inverter><SubTree ID="T{i + 1}"/></Inverter></BehaviorTree>'
        for i in range(150)
    )
    last = '<BehaviorTree ID="T150"><AlwaysSuccess/></BehaviorTree>'
    xml = f'<root BTCPP_format="4" main_tree_to_execute="T0">{trees}{last}</root>'
    registry = bt.NodeRegistry.with_builtins()
    doc = bt.load_tree_text(xml, registry)
    with pytest.raises(bt.BTLoadError, match=r"more than 200 nodes deep through its SubTrees \(T0 -> T1 -> "):
        bt.build_tree(doc, registry)
