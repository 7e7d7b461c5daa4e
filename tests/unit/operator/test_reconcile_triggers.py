"""The reconcilers skip their own status writes and re-run on new inputs or after a failed pass."""

from __future__ import annotations

from typing import Any

import pytest
from coral_operator.api import names
from coral_operator.handlers import triggers


def test_a_pass_is_skipped_only_for_inputs_already_handled() -> None:
    triggers.handled("uid-a", (1, "pods-x"))
    assert triggers.already_handled("uid-a", (1, "pods-x"))
    assert not triggers.already_handled("uid-a", (1, "pods-y")), "a poke is a new input"
    assert not triggers.already_handled("uid-a", (2, "pods-x")), "a spec change is a new input"
    triggers.forget("uid-a")
    assert not triggers.already_handled("uid-a", (1, "pods-x"))


def test_a_poke_writes_each_digest_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """The API write is replaced by a recorder: this checks the de-duplication, not the API."""
    writes: list[tuple[Any, ...]] = []
    monkeypatch.setattr(triggers.applying, "annotate", lambda *args: writes.append(args))
    triggers.poke("coralinstances", "ns", "sys-r1", "pods-1")
    triggers.poke("coralinstances", "ns", "sys-r1", "pods-1")
    triggers.poke("coralinstances", "ns", "sys-r1", "pods-2")
    assert [w[3][names.ANNOTATION_OBSERVED] for w in writes] == ["pods-1", "pods-2"]


def test_a_failed_write_is_not_remembered(monkeypatch: pytest.MonkeyPatch) -> None:
    """The API failure is simulated: a refused poke must be retried by the next identical poke."""
    calls: list[str] = []

    def refuse(*args: Any) -> None:
        calls.append(args[3][names.ANNOTATION_OBSERVED])
        raise RuntimeError("API unavailable")

    monkeypatch.setattr(triggers.applying, "annotate", refuse)
    for _ in range(2):
        with pytest.raises(RuntimeError):
            triggers.poke("coralsystems", "ns", "sys", "robots-1")
    assert calls == ["robots-1", "robots-1"]


def test_the_operator_registers_no_change_handlers_so_it_needs_no_diff_base() -> None:
    """The settings skip kopf's per-event essence; that is right only while no handler compares one."""
    import kopf
    from coral_operator import handlers  # noqa: F401  (registers every handler)
    from coral_operator.handlers.settings import EssenceFreeDiffBase

    registry = kopf.get_default_registry()
    assert list(registry._changing.get_all_handlers()) == []
    assert list(registry._watching.get_all_handlers()), "the event handlers are registered"
    assert EssenceFreeDiffBase(prefix="coral.dev").build(body=kopf.Body({"spec": {"a": 1}})) == {}
