"""Rollout tests name the operator fixture `operator` (see tests/fixtures/operator.py)."""

from collections.abc import Iterator

import pytest
from fixtures.operator import OperatorProcess


@pytest.fixture
def operator(coral_operator: OperatorProcess) -> Iterator[OperatorProcess]:
    yield coral_operator
