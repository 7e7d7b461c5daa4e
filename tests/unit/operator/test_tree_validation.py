"""The operator judges a tree the way the robots' executors will load it."""

from coral_operator.planning import validation

SCRIPTED_TREE = """<root BTCPP_format="4">
  <BehaviorTree ID="Main">
    <Sequence>
      <Script code="a := 1; b := 2" />
      <ScriptCondition code="a < b && b == 2" />
      <Navigate goal="{goal}" />
    </Sequence>
  </BehaviorTree>
</root>
"""


def test_raw_ampersands_and_less_than_in_scripts_are_accepted_as_bt_cpp_accepts_them() -> None:
    """A strict XML parser rejects `&&` and `<` inside attributes; BT.CPP (tinyxml2) does not,
    and real trees rely on it, so refusing them would stall valid missions."""
    assert validation.validate_tree(SCRIPTED_TREE, "tree.xml") == []


def test_a_wrong_child_count_is_reported_with_file_and_line() -> None:
    bad = SCRIPTED_TREE.replace("<Sequence>", "<Inverter>").replace("</Sequence>", "</Inverter>")
    problems = validation.validate_tree(bad, "tree.xml")
    assert problems and problems[0].startswith("tree.xml:3:"), problems


def test_malformed_xml_is_reported_with_file_and_line() -> None:
    problems = validation.validate_tree("<root BTCPP_format='4'>\n  <BehaviorTree ID='M'>\n", "t.xml")
    assert len(problems) == 1 and problems[0].startswith("t.xml:"), problems
