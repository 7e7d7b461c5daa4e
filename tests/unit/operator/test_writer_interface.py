"""The writer the operator runs with and the one the reconcile tests use make the same calls.

The reconcilers call the API only through `kube.writer.Writer`; a call the fake lacks, or takes
other parameters for, would let a unit test pass over a pass the operator cannot make.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable

import pytest
from coral_operator.kube.writer import KubeWriter, Writer
from fake_writer import FakeWriter

CALLS = sorted(
    name for name, member in vars(Writer).items() if inspect.isfunction(member) and not name.startswith("_")
)


def _parameters(function: Callable[..., object]) -> list[str]:
    return [name for name in inspect.signature(function).parameters if name != "self"]


@pytest.mark.parametrize("call", CALLS)
def test_the_operators_writer_and_the_fake_take_each_call_alike(call: str) -> None:
    expected = _parameters(getattr(Writer, call))
    assert _parameters(getattr(KubeWriter(), call)) == expected
    assert _parameters(getattr(FakeWriter(), call)) == expected
