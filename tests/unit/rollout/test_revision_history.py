"""Revision history kept as ControllerRevisions: the newest is stored and numbered highest, the
oldest are pruned beyond the limit unless a robot still runs them."""

from __future__ import annotations

from coral_operator.planning.revisions import (
    StoredRevision,
    build_revision,
    plan_history,
    template_of_instance,
)


def stored(revision: str, number: int) -> StoredRevision:
    return StoredRevision(name=f"patrol-{revision}", revision=revision, number=number, template={"ros": {}})


def plan(existing: list[StoredRevision], revision: str, in_use: set[str] = frozenset(), limit: int = 3):
    return plan_history(
        stored=existing,
        system="patrol",
        namespace="fleet",
        system_uid="uid-1",
        revision=revision,
        template={"ros": {"domainId": 3}},
        in_use=set(in_use),
        limit=limit,
    )


def test_a_new_revision_is_stored_with_the_next_number_and_owned_by_its_system() -> None:
    result = plan([stored("aaa", 1)], "bbb")
    assert result.create["kind"] == "ControllerRevision" and result.create["revision"] == 2
    assert result.create["data"] == {"ros": {"domainId": 3}}
    assert result.create["metadata"]["ownerReferences"][0]["uid"] == "uid-1"
    assert result.create["metadata"]["labels"]["coral.dev/revision"] == "bbb"
    assert result.order == ["aaa", "bbb"]


def test_the_newest_revision_already_stored_changes_nothing() -> None:
    result = plan([stored("aaa", 1), stored("bbb", 2)], "bbb")
    assert result.create is None and result.renumber is None and result.delete == []


def test_going_back_to_an_older_revision_renumbers_it_as_the_newest() -> None:
    result = plan([stored("aaa", 1), stored("bbb", 2)], "aaa")
    assert result.renumber == ("patrol-aaa", 3)
    assert result.order == ["bbb", "aaa"]


def test_the_oldest_revisions_beyond_the_limit_are_pruned_unless_a_robot_runs_them() -> None:
    existing = [stored("r1", 1), stored("r2", 2), stored("r3", 3)]
    result = plan(existing, "r4", in_use={"r1"})
    assert result.delete == ["patrol-r2"]
    assert result.order == ["r1", "r3", "r4"]


def test_an_instance_spec_gives_back_the_template_it_was_built_from() -> None:
    spec = {"system": "patrol", "robot": "r1", "nodeName": "n1", "revision": "x", "ros": {}, "tree": {}}
    assert template_of_instance(spec) == {"ros": {}, "tree": {}}
    manifest = build_revision(
        system="patrol", namespace="fleet", system_uid="u", revision="x", template={}, number=1
    )
    assert manifest["metadata"]["name"] == "patrol-x"
