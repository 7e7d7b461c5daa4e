"""Parameters YAML is measured before anything is built from it, on the operator and on the robot.

Issue 47: parameters of a few hundred bytes with nested merge keys (`<<`) expanded to millions of
entries, 30 s of CPU and 445 MB per pass, and one level more OOM-killed the operator in a loop.
The bounds are checked on the parser's event stream, so measuring a bomb costs what reading its
text costs, and the refusal names the figure.
"""

from __future__ import annotations

import time
import tracemalloc

import pytest
import yaml
from coral.sdk import params
from coral_core import parsing
from coral_operator.planning import validation
from fixtures.yaml_bombs import merge_bomb

FILE = "coralsystem/x spec.parameters.inline"


def big_valid_parameters(nodes: int = 400, per_node: int = 40) -> str:
    """About 230 KB of ordinary parameters: many nodes, many values, no alias."""
    return "".join(
        f"node{i}:\n  ros__parameters:\n" + "".join(f"    p{j}: {j}.5\n" for j in range(per_node))
        for i in range(nodes)
    )


def test_a_merge_key_bomb_is_refused_with_its_expansion_and_the_limit() -> None:
    (problem,) = validation.validate_parameters(merge_bomb(6), FILE)
    assert problem == f"{FILE}:5: expands to 43,261,517 entries; the limit is 100,000"


def test_a_merge_key_bomb_one_level_up_costs_no_more_to_refuse() -> None:
    text = merge_bomb(9)
    tracemalloc.start()
    started = time.process_time()
    try:
        (problem,) = validation.validate_parameters(text, FILE)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert "expands to 57,581,082,611 entries; the limit is 100,000" in problem
    assert time.process_time() - started < 0.5
    assert peak < 1_000_000


def test_an_alias_bomb_without_merge_keys_is_refused_too() -> None:
    laughs = ["a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    laughs += [f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join([f'*{chr(97 + i)}'] * 10)}]" for i in range(8)]
    (problem,) = validation.validate_parameters("\n".join(laughs) + "\n", FILE)
    assert "entries; the limit is 100,000" in problem


def test_too_many_aliases_are_refused_even_when_each_is_small() -> None:
    text = "a: &a 1\nb: [" + ", ".join(["*a"] * 1500) + "]\n"
    (problem,) = validation.validate_parameters(text, FILE)
    assert problem == f"{FILE}:2: has 1,500 aliases; the limit is 1,000"


def test_too_many_merge_keys_are_refused() -> None:
    text = "base: &b {x: 1}\n" + "".join(f"n{i}: {{<<: *b}}\n" for i in range(1200))
    (problem,) = validation.validate_parameters(text, FILE)
    assert "merge keys (<<)" in problem and "the limit is 1,000" in problem


def test_a_few_merge_keys_are_ordinary_yaml() -> None:
    text = (
        "defaults: &defaults {ros__parameters: {rate: 10, frame: map}}\n"
        "planner:\n  <<: *defaults\ncontroller:\n  <<: *defaults\n"
    )
    assert validation.validate_parameters(text, FILE) == []
    assert params.validate_text(text)["planner"]["ros__parameters"]["rate"] == 10


def test_an_alias_to_its_own_container_is_refused() -> None:
    (problem,) = validation.validate_parameters("a: &x [1, *x]\n", FILE)
    assert problem == f"{FILE}:1: the alias *x refers to a node that contains it"


@pytest.mark.parametrize("depth", [65, 5000])
def test_deep_nesting_is_refused_without_recursion(depth: int) -> None:
    (problem,) = validation.validate_parameters("a: " + "[" * depth + "]" * depth + "\n", FILE)
    assert problem == f"{FILE}:1: invalid YAML: the document nests too deeply to be read"


def test_nesting_within_the_bound_is_read() -> None:
    assert validation.validate_parameters("a: " + "[" * 60 + "]" * 60 + "\n", FILE) == []


def test_a_python_tag_is_refused_before_anything_is_built() -> None:
    (problem,) = validation.validate_parameters("a: !!python/object/apply:os.system [id]\n", FILE)
    assert problem.startswith(f"{FILE}:1: invalid YAML: could not determine a constructor for the tag")


def test_big_but_valid_parameters_pass_quickly_on_both_sides() -> None:
    text = big_valid_parameters()
    assert len(text) > 200_000
    started = time.process_time()
    assert validation.validate_parameters(text, FILE) == []
    assert time.process_time() - started < 2.0
    assert len(params.validate_text(text)) == 400


def test_a_known_verdict_is_not_computed_again() -> None:
    verdicts = validation.Verdicts(size=2)
    bomb = merge_bomb(6)
    first = validation.validate_parameters(bomb, FILE, verdicts)
    started = time.process_time()
    for _ in range(50):
        assert validation.validate_parameters(bomb, FILE, verdicts) == first
    assert time.process_time() - started < 0.2
    # Bounded: older verdicts are dropped.
    for i in range(5):
        validation.validate_parameters(f"n{i}: {{}}\n", FILE, verdicts)
    assert len(verdicts._kept) == 2


def test_the_robot_refuses_the_same_bomb_naming_the_file_and_line() -> None:
    with pytest.raises(params.ParamsError) as refused:
        params.validate_text(merge_bomb(6), "params.yaml")
    assert str(refused.value) == "params.yaml:5: expands to 43,261,517 entries; the limit is 100,000"


def test_check_yaml_reports_the_root_kind() -> None:
    assert parsing.check_yaml("a: 1\n") == "mapping"
    assert parsing.check_yaml("- 1\n") == "sequence"
    assert parsing.check_yaml("just text\n") == "scalar"
    assert parsing.check_yaml("") is None
    with pytest.raises(yaml.YAMLError):
        parsing.check_yaml("a: [\n")


def test_other_limits_can_be_chosen() -> None:
    small = parsing.YamlLimits(max_entries=5)
    with pytest.raises(parsing.OverLimit) as refused:
        parsing.check_yaml("[1, 2, 3, 4, 5, 6]\n", small)
    assert refused.value.problem == "expands to 7 entries; the limit is 5"


def test_an_undefined_alias_is_named_with_its_line() -> None:
    (problem,) = validation.validate_parameters("a: 1\nb: *nowhere\n", FILE)
    assert problem == f"{FILE}:2: invalid YAML: found undefined alias 'nowhere'"
