"""Reads what the executor wrote into a CoralInstance's status (`tree`, `plugins`) defensively.

The executor's account may write anything the CRD's schema admits, and a CRD installed by an
older chart may admit more. A value the operator cannot read (a `tree.updatedAt` that is no
RFC 3339 time, a `plugins.missing` that is no list of names) is dropped and named in a sentence,
never raised: an exception here used to stop every pass of the instance before it wrote its own
conditions, so a forged `Ready=True` stuck (issue 47, item 5). The sentences reach the
`TreeHealthy` and `PluginsReady` conditions (`status.instance_status`). What remains is read into
the models the executor's sink wrote from (`coral_core.instance_status`). Pure; called by
`reconcile.instances` once per pass.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from coral_core.instance_status import PARK_STATUSES, ROOT_STATUSES, PluginState, TreeState

from coral_operator.api import keys
from coral_operator.status.transitions import parse_rfc3339

# A forged value is quoted to say what was ignored, never whole: it could be 1 MB long.
_QUOTED = 40
_MAX_ENTRIES = 1000
_MAX_TEXT = 32768


@dataclass(frozen=True)
class ExecutorReport:
    """The executor's fields the operator can read, and a sentence per field it ignored."""

    tree: TreeState | None = None
    plugins: PluginState | None = None
    ignored_tree: list[str] = field(default_factory=list)
    ignored_plugins: list[str] = field(default_factory=list)


def _quoted(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= _QUOTED else text[: _QUOTED - 3] + "..."


def _is_text(value: Any) -> bool:
    return isinstance(value, str) and len(value) <= _MAX_TEXT


def _is_time(value: Any) -> bool:
    if not isinstance(value, str) or len(value) > 64:
        return False
    try:
        moment = parse_rfc3339(value)
    except (ValueError, TypeError, OverflowError):
        return False
    # A time without a zone cannot be compared with the API server's, which all have one.
    return isinstance(moment, datetime) and moment.tzinfo is not None


def _is_count(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def _is_names(value: Any) -> bool:
    return isinstance(value, list) and len(value) <= _MAX_ENTRIES and all(_is_text(v) for v in value)


@dataclass(frozen=True)
class _ObjectCheck:
    """A check of an optional object whose present fields each pass theirs; `known` keeps those
    fields only (a key the schema does not know is nothing anyone reads)."""

    checks: Mapping[str, Callable[[Any], bool]]

    def __call__(self, value: Any) -> bool:
        if value is None:
            return True
        if not isinstance(value, Mapping):
            return False
        return all(check(value[key]) for key, check in self.checks.items() if key in value)

    def known(self, value: Mapping[str, Any] | None) -> dict[str, Any] | None:
        return None if value is None else {k: v for k, v in value.items() if k in self.checks}


def _is_optional_time(value: Any) -> bool:
    return value is None or _is_time(value)


_is_failure = _ObjectCheck(
    {
        keys.TREE_FAILURE.path: _is_text,
        keys.TREE_FAILURE.message: _is_text,
        keys.TREE_FAILURE.time: _is_optional_time,
    }
)
_is_no_progress = _ObjectCheck(
    {
        keys.NO_PROGRESS.path: _is_text,
        keys.NO_PROGRESS.message: _is_text,
        keys.NO_PROGRESS.since: _is_optional_time,
    }
)

_is_halt = _ObjectCheck(
    {
        keys.TREE_HALT.since: _is_optional_time,
        keys.TREE_HALT.park_tree: lambda v: v is None or _is_text(v),
        keys.TREE_HALT.park_status: lambda v: v is None or v in PARK_STATUSES,
    }
)


_TREE_FIELDS: dict[str, tuple[Callable[[Any], bool], str]] = {
    keys.TREE.root_status: (
        lambda v: isinstance(v, str) and v in ROOT_STATUSES,
        "one of " + ", ".join(sorted(ROOT_STATUSES)),
    ),
    keys.TREE.active_path: (_is_text, "a string"),
    keys.TREE.tick_count: (_is_count, "a count"),
    keys.TREE.last_transition_time: (_is_optional_time, "an RFC 3339 time"),
    keys.TREE.last_failure: (_is_failure, "an object of path, message and RFC 3339 time"),
    keys.TREE.no_progress: (_is_no_progress, "an object of path, message and RFC 3339 time"),
    keys.TREE.halted: (_is_halt, "an object of RFC 3339 time, park tree and park status"),
    keys.TREE.message: (_is_text, "a string"),
    keys.TREE.updated_at: (_is_optional_time, "an RFC 3339 time"),
}
_PLUGIN_FIELDS: dict[str, tuple[Callable[[Any], bool], str]] = {
    keys.PLUGINS.loaded: (_is_names, "a list of names"),
    keys.PLUGINS.missing: (_is_names, "a list of names"),
    keys.PLUGINS.conflicts: (_is_names, "a list of sentences"),
    keys.PLUGINS.degraded: (_is_names, "a list of names"),
}


def _read(
    value: Any, where: str, fields: Mapping[str, tuple[Callable[[Any], bool], str]]
) -> tuple[dict[str, Any] | None, list[str]]:
    if value is None:
        return None, []
    if not isinstance(value, Mapping):
        return None, [f"{where}: {_quoted(value)} is not an object"]
    kept: dict[str, Any] = {}
    ignored: list[str] = []
    for key, item in value.items():
        check = fields.get(key) if isinstance(key, str) else None
        if check is None:
            continue  # not a field of the schema: nothing reads it
        if not check[0](item):
            ignored.append(f"{where}.{key}: {_quoted(item)} is not {check[1]}")
        else:
            kept[key] = check[0].known(item) if isinstance(check[0], _ObjectCheck) else item
    # Nothing readable is no report at all, as for an executor that has not written yet.
    return kept or None, ignored


def read_executor_report(status: Mapping[str, Any]) -> ExecutorReport:
    """The executor's `tree` and `plugins` with every field the operator cannot read left out."""
    tree, ignored_tree = _read(status.get(keys.INSTANCE_STATUS.tree), "status.tree", _TREE_FIELDS)
    plugins, ignored_plugins = _read(
        status.get(keys.INSTANCE_STATUS.plugins), "status.plugins", _PLUGIN_FIELDS
    )
    # What passed the checks is valid for the models: they admit more than the checks do.
    return ExecutorReport(
        tree=None if tree is None else TreeState.model_validate(tree),
        plugins=None if plugins is None else PluginState.model_validate(plugins),
        ignored_tree=ignored_tree,
        ignored_plugins=ignored_plugins,
    )


def ignored_note(ignored: list[str]) -> str:
    """The sentence appended to a condition's message, naming what was ignored; empty if nothing."""
    if not ignored:
        return ""
    return " Ignored what the executor wrote: " + "; ".join(ignored) + "."
