"""`coral_operator.api` re-exports every public model of its modules and of the contract's
(`coral_core.wire`, `coral_core.instance_status`), and `__all__` lists exactly those."""

from __future__ import annotations

import inspect

from coral_core import instance_status, wire
from coral_operator import api
from coral_operator.api import common, components, instance, system
from pydantic import BaseModel


def test_every_public_model_is_exported() -> None:
    models = {
        name
        for module in (wire, instance_status, common, components, instance, system)
        for name, value in vars(module).items()
        if inspect.isclass(value) and issubclass(value, BaseModel) and value.__module__ == module.__name__
    }
    assert models <= set(api.__all__)


def test_all_names_only_what_exists() -> None:
    assert sorted(api.__all__) == sorted(set(api.__all__))
    for name in api.__all__:
        assert hasattr(api, name), name
