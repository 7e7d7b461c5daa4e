"""The pydantic models refuse what the CRD's CEL rules refuse, with the same messages."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from coral_operator.api import system
from pydantic import ValidationError

CASES = [
    ("refuse an empty robot selector", {"robots": {}}, system.ROBOTS_NOT_EMPTY),
    (
        "refuse a privileged skillset",
        {"skillsets": [{"name": "slam", "image": "s", "privileged": True}]},
        system.PRIVILEGED_DRIVERS_ONLY,
    ),
    (
        "refuse a name used by a driver and an executor",
        {"executors": [{"name": "lidar", "image": "e"}]},
        system.UNIQUE_NAMES,
    ),
    ("refuse a system without executors", {"executors": []}, system.NEEDS_EXECUTOR),
    ("refuse a domain id above 232", {"ros": {"domainId": 233}}, system.DOMAIN_RANGE),
    (
        "refuse a tree given both inline and by ConfigMap",
        {"tree": {"inline": "<root/>", "configMapRef": {"name": "t", "key": "tree.xml"}}},
        system.SOURCE_EXACTLY_ONE,
    ),
    ("refuse parameters given neither way", {"parameters": {}}, system.SOURCE_EXACTLY_ONE),
    ("refuse an unknown field", {"robotz": {}}, "Extra inputs are not permitted"),
    (
        "refuse a ConfigMap name the API server cannot take",
        {"parameters": {"configMapRef": {"name": "params%2f", "key": "p.yaml"}}},
        r"parameters\.configMapRef\.name\n  String should match pattern",
    ),
    (
        "refuse a ConfigMap key the API server cannot take",
        {"tree": {"configMapRef": {"name": "trees", "key": "../tree.xml/"}}},
        r"tree\.configMapRef\.key\n  String should match pattern",
    ),
    (
        "refuse two overrides of one name",
        {"overrides": [{"name": "a", "robots": {"matchLabels": {"m": "x"}}}] * 2},
        system.OVERRIDE_NAMES_UNIQUE,
    ),
    (
        "refuse an override selecting nothing",
        {"overrides": [{"name": "a", "robots": {}}]},
        "must select with at least one label",
    ),
    (
        "refuse an override tree file under the tree's own name",
        {
            "overrides": [
                {"name": "a", "robots": {"matchLabels": {"m": "x"}}, "tree": {"files": {"tree.xml": "x"}}}
            ]
        },
        "tree file names are file names",
    ),
    (
        "refuse a component name that is not a DNS label",
        {"drivers": [{"name": "Lidar_1", "image": "l"}]},
        "String should match pattern",
    ),
]


@pytest.mark.parametrize(("story", "change", "message"), CASES, ids=[c[0] for c in CASES])
def test_invalid_specs_are_refused_with_the_rule_message(
    spec_dict: Callable[..., dict[str, Any]], story: str, change: dict[str, Any], message: str
) -> None:
    with pytest.raises(ValidationError, match=message):
        system.CoralSystemSpec.model_validate(spec_dict(**change))


def test_a_privileged_driver_is_accepted(spec_dict: Callable[..., dict[str, Any]]) -> None:
    spec = system.CoralSystemSpec.model_validate(
        spec_dict(drivers=[{"name": "lidar", "image": "l", "privileged": True}])
    )
    assert spec.drivers[0].privileged


def test_defaults_follow_coral_compose_files(spec_dict: Callable[..., dict[str, Any]]) -> None:
    spec = system.CoralSystemSpec.model_validate(spec_dict())
    assert spec.ros.network == "Host"
    assert spec.ros.domain_id == 0
    assert spec.startup.on_timeout == "Block"
    assert spec.rollout.max_unavailable == "25%"
