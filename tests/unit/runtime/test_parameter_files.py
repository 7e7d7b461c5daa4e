"""Parameters YAML: rcl's node-name matching, and errors that name the file and line."""

from __future__ import annotations

import pytest
from coral.sdk import params

DOCUMENT = """
/**:
  ros__parameters:
    use_sim_time: false
    limits: {speed: 1.5}
robot1/*:
  ros__parameters:
    fleet: a
examples:
  ros__parameters:
    work_delay_s: 0.5
    use_sim_time: true
"""


@pytest.mark.parametrize(
    ("node", "expected"),
    [
        ("/examples", {"use_sim_time": True, "limits.speed": 1.5, "work_delay_s": 0.5}),
        ("/robot1/slam", {"use_sim_time": False, "limits.speed": 1.5, "fleet": "a"}),
        ("/robot1/deep/slam", {"use_sim_time": False, "limits.speed": 1.5}),
        ("/other", {"use_sim_time": False, "limits.speed": 1.5}),
    ],
)
def test_wildcards_select_parameters_like_params_file(node: str, expected: dict[str, object]) -> None:
    assert params.parameters_for(params.validate_text(DOCUMENT), node) == expected


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("a: [1\n", r"^p\.yaml:2: invalid YAML"),
        ("- 1\n", r"^p\.yaml:1: a parameters file must map node names"),
        ("node:\n  ros__parameters: 3\n", r"^p\.yaml:2: 'ros__parameters' must be a mapping"),
        ("node:\n  ros__parameters: {a: 1}\n  extra: 2\n", r"^p\.yaml:3: unexpected key 'extra'"),
        (
            "node:\n  ros__parameters:\n    a: [{x: 1}]\n",
            r"^p\.yaml:3: parameter 'a' arrays may hold scalars only",
        ),
    ],
)
def test_a_bad_parameters_file_names_file_and_line(text: str, message: str) -> None:
    with pytest.raises(params.ParamsError, match=message):
        params.validate_text(text, "p.yaml")
