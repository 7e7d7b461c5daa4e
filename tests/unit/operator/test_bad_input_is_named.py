"""Bad trees, parameters and privilege requests are refused with the file, line or field."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from coral_operator import config
from coral_operator.api.system import CoralSystemSpec
from coral_operator.planning import policy, validation
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


def test_the_default_policy_allows_everything(spec_dict: Callable[..., dict[str, Any]]) -> None:
    spec = CoralSystemSpec.model_validate(
        spec_dict(drivers=[{"name": "d", "image": "d", "privileged": True}])
    )
    assert policy.evaluate_policy("ns", spec, config.from_environment({}).policy) == []


def test_a_restricted_policy_names_every_violation(spec_dict: Callable[..., dict[str, Any]]) -> None:
    spec = CoralSystemSpec.model_validate(
        spec_dict(
            drivers=[
                {
                    "name": "lidar",
                    "image": "l",
                    "privileged": True,
                    "devices": [{"hostPath": "/dev/ttyUSB0"}],
                    "hostPaths": [{"hostPath": "/etc", "mountPath": "/etc"}],
                }
            ]
        )
    )
    restricted = config.from_environment(
        {
            "CORAL_POLICY_PRIVILEGED_NAMESPACES": "hardware",
            "CORAL_POLICY_HOST_PATH_PREFIXES": "/dev,/var/lib/coral",
            "CORAL_POLICY_HOST_NETWORK_NAMESPACES": "hardware",
        }
    ).policy
    problems = policy.evaluate_policy("ns", spec, restricted)
    assert problems == [
        "spec.ros.network: host network is not allowed in namespace ns",
        "spec.drivers[0] (lidar): privileged is not allowed in namespace ns",
        "spec.drivers[0] (lidar): host path /etc is outside the allowed prefixes (/dev, /var/lib/coral)",
    ]
    assert policy.evaluate_policy("hardware", spec, restricted) == [problems[2]]
