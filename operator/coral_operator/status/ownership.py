"""Who owns which part of a CoralInstance's status (docs/architecture.md).

The executor writes `tree` and `plugins`; everything else is the operator's, recomputed from
what it observes on every pass. The executor's account may patch the status subresource (RBAC
cannot narrow a patch to fields), so whatever it writes into the operator's part is treated as
a change to correct, never as input. Pure; used by the instance handler.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from coral_operator.api import keys

EXECUTOR_KEYS = frozenset({keys.INSTANCE_STATUS.tree, keys.INSTANCE_STATUS.plugins})


def operator_part(status: Mapping[str, Any]) -> dict[str, Any]:
    """The fields of `status` the operator computes."""
    return {key: value for key, value in status.items() if key not in EXECUTOR_KEYS}


def executor_part(status: Mapping[str, Any]) -> dict[str, Any]:
    """The fields of `status` the executor reports."""
    return {key: value for key, value in status.items() if key in EXECUTOR_KEYS}
