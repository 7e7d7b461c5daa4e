"""An object a system needs, found under its name but owned by an earlier system of the same name,
is handed to the new system; one that is another owner's is left alone and reported
(`NameTaken`); one deleted between the 409 and the read is created again. The API calls are
in-memory stand-ins holding one object, so each of those orders can be chosen; the real sequence
runs in the integration test of a system created again under its name."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest
from coral_operator.kube.applying import NameTaken, create_owned
from kubernetes.client.exceptions import ApiException

LABELS = {"coral.dev/system": "fleet", "app.kubernetes.io/managed-by": "coral-operator"}


def _manifest(uid: str) -> dict[str, Any]:
    return {
        "kind": "ServiceAccount",
        "metadata": {
            "name": "coral-executor-fleet",
            "namespace": "robots",
            "labels": dict(LABELS),
            "ownerReferences": [{"kind": "CoralSystem", "name": "fleet", "uid": uid}],
        },
    }


class OneObjectStore:
    """The one object under a name, with the reads and writes `create_owned` makes."""

    def __init__(
        self, labels: dict[str, str], owner: str | None, vanish_on_read: int = 0, owner_name: str = "fleet"
    ) -> None:
        reference = {"kind": "CoralSystem", "name": owner_name, "uid": owner}
        self.object: dict[str, Any] | None = (
            {"labels": labels, "owners": [reference]} if owner is not None else None
        )
        self.vanish_on_read = vanish_on_read
        self.calls: list[str] = []

    def create(self, namespace: str, manifest: dict[str, Any]) -> None:
        self.calls.append("create")
        if self.object is not None:
            raise ApiException(status=409, reason="AlreadyExists")
        metadata = manifest["metadata"]
        self.object = {"labels": metadata["labels"], "owners": metadata["ownerReferences"]}

    def read(self, name: str, namespace: str) -> SimpleNamespace:
        self.calls.append("read")
        if self.vanish_on_read:
            # The garbage collector deleting the old object between the 409 and the read.
            self.vanish_on_read -= 1
            self.object = None
        if self.object is None:
            raise ApiException(status=404, reason="NotFound")
        owners = [SimpleNamespace(**o) for o in self.object["owners"]]
        metadata = SimpleNamespace(labels=self.object["labels"], owner_references=owners)
        return SimpleNamespace(metadata=metadata)

    def take_over(self, current: Any, manifest: dict[str, Any]) -> None:
        self.calls.append("take over")
        assert self.object is not None
        self.object["owners"] = manifest["metadata"]["ownerReferences"]

    def owner(self) -> str | None:
        return None if self.object is None else self.object["owners"][0]["uid"]


def _create(store: OneObjectStore, uid: str) -> None:
    create_owned(_manifest(uid), store.create, store.read, store.take_over)


def test_an_object_left_by_an_earlier_system_of_the_name_becomes_the_new_ones() -> None:
    store = OneObjectStore(LABELS, owner="old")
    _create(store, "new")
    assert store.owner() == "new"
    assert store.calls == ["create", "read", "take over"]


def test_an_object_the_system_already_owns_is_not_written_again() -> None:
    store = OneObjectStore(LABELS, owner="new")
    _create(store, "new")
    assert store.calls == ["create", "read"]


def test_an_object_without_the_operators_labels_is_not_taken_and_is_reported() -> None:
    store = OneObjectStore({"app": "someone-else"}, owner="theirs")
    with pytest.raises(NameTaken, match="ServiceAccount coral-executor-fleet .* CoralSystem fleet"):
        _create(store, "new")
    assert store.owner() == "theirs"
    assert "take over" not in store.calls


def test_an_object_with_the_systems_labels_but_another_systems_ownership_is_not_taken() -> None:
    """Issue 47, item 9: a second system whose names shortened like the first's took over the
    first's ServiceAccount (same labels, another owner), and deleting it deleted the first's."""
    store = OneObjectStore(LABELS, owner="victim-uid", owner_name="victim")
    with pytest.raises(NameTaken, match="belongs to CoralSystem victim"):
        _create(store, "new")
    assert store.owner() == "victim-uid"
    assert "take over" not in store.calls


def test_an_object_orphaned_by_the_systems_predecessor_is_taken() -> None:
    store = OneObjectStore(LABELS, owner="old")
    assert store.object is not None
    store.object["owners"] = []
    _create(store, "new")
    assert store.owner() == "new"


def test_an_object_deleted_after_the_conflict_is_created_again() -> None:
    store = OneObjectStore(LABELS, owner="old", vanish_on_read=1)
    _create(store, "new")
    assert store.owner() == "new"
    assert store.calls == ["create", "read", "create"]


def test_an_object_that_never_settles_is_an_error_not_a_silent_success() -> None:
    store = OneObjectStore(LABELS, owner="old", vanish_on_read=1)

    def recreated_by_someone_else(namespace: str, manifest: dict[str, Any]) -> None:
        store.calls.append("create")
        store.object = {"labels": LABELS, "owners": [{"uid": "old"}]}
        store.vanish_on_read = 1
        raise ApiException(status=409, reason="AlreadyExists")

    with pytest.raises(RuntimeError, match="kept changing"):
        create_owned(_manifest("new"), recreated_by_someone_else, store.read, store.take_over)
