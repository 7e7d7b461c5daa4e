"""Bad trees, parameters and privilege requests are refused with the file, line or field."""

from __future__ import annotations

from coral_operator.planning import validation
from operator_specs import TREE


def test_a_valid_tree_passes() -> None:
    assert validation.validate_tree(TREE, "tree.xml") == []


def test_malformed_xml_names_file_and_line() -> None:
    problems = validation.validate_tree(
        "<root>\n<BehaviorTree ID='a'>\n</Sequence>\n</root>", "configmap/m/tree.xml"
    )
    assert len(problems) == 1
    assert problems[0].startswith("configmap/m/tree.xml:3:")


def test_a_missing_main_tree_is_named() -> None:
    problems = validation.validate_tree(TREE, "tree.xml", main_tree_id="Other")
    assert problems and "Other" in problems[0]


def test_a_document_without_trees_is_refused() -> None:
    assert "no <BehaviorTree>" in validation.validate_tree("<root/>", "t.xml")[0]


def test_invalid_parameters_yaml_names_the_line() -> None:
    problems = validation.validate_parameters("a:\n  b: 1\n c: [\n", "params.yaml")
    assert problems and problems[0].startswith("params.yaml:3:")


def test_parameters_must_be_a_mapping() -> None:
    assert "mapping" in validation.validate_parameters("- a\n- b\n", "params.yaml")[0]
    assert validation.validate_parameters("", "params.yaml") == []
