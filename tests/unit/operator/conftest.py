"""Fixtures of the operator's unit tests."""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import pytest
from operator_specs import BASE_SPEC


@pytest.fixture
def spec_dict() -> Callable[..., dict[str, Any]]:
    """A fresh copy of a valid spec, with top-level fields replaced by the keyword arguments."""

    def build(**changes: Any) -> dict[str, Any]:
        spec = copy.deepcopy(BASE_SPEC)
        spec.update(changes)
        return spec

    return build
