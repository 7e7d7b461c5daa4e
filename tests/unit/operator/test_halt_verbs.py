"""`coral halt` and `coral resume` write `spec.halt` (robots add up, a lifted halt goes away), race
other writers safely, and `--wait` waits for every robot's executor to acknowledge."""

from __future__ import annotations

import copy
from typing import Any

import pytest
from click.testing import CliRunner
from coral_operator import halt_control
from coral_operator.api.system import HaltSpec
from coral_operator.halt_cli import halt_command, resume_command
from kubernetes.client.exceptions import ApiException


def test_halting_robots_one_by_one_adds_them_up_and_a_fleet_halt_covers_every_robot() -> None:
    one = halt_control.halted(None, "r2", None, 30)
    two = halt_control.halted(one, "r1", "GoHome", 10)
    assert (two.robots, two.park_tree, two.park_timeout_seconds) == (["r1", "r2"], "GoHome", 10)
    assert halt_control.halted(HaltSpec(), "r1", None, 30).robots == [], "already halted with the fleet"
    assert halt_control.halted(two, None, None, 30).robots == []


def test_resuming_removes_the_robot_and_the_last_one_lifts_the_halt() -> None:
    both = HaltSpec(robots=["r1", "r2"])
    left = halt_control.resumed(both, "r1", "mission")
    assert left is not None and left.robots == ["r2"]
    assert halt_control.resumed(left, "r2", "mission") is None
    assert halt_control.resumed(both, None, "mission") is None
    with pytest.raises(halt_control.HaltError, match="every robot of coralsystem/mission is halted"):
        halt_control.resumed(HaltSpec(), "r1", "mission")


class _Api:
    """The CustomObjectsApi calls the verbs make, over one CoralSystem and its instances; each
    instance's executor acknowledges what its spec asks when `acknowledging` names its robot."""

    def __init__(self, conflicts: int = 0, acknowledging: tuple[str, ...] = ("r1", "r2")) -> None:
        self.system: dict[str, Any] = {"metadata": {"name": "mission", "resourceVersion": "1"}, "spec": {}}
        self.patches: list[dict[str, Any]] = []
        self.conflicts = conflicts
        self.acknowledging = acknowledging

    def get_namespaced_custom_object(self, *address: str) -> dict[str, Any]:
        if address[-1] != "mission":
            raise ApiException(status=404)
        return copy.deepcopy(self.system)

    def patch_namespaced_custom_object(self, *args: Any, **_: Any) -> None:
        body = args[5]
        self.patches.append(body)
        if (
            self.conflicts
            or body["metadata"]["resourceVersion"] != self.system["metadata"]["resourceVersion"]
        ):
            self.conflicts = max(0, self.conflicts - 1)
            self.system["metadata"]["resourceVersion"] += "+"  # another writer came first
            raise ApiException(status=409)
        halt = body["spec"]["halt"]
        if halt is None:
            self.system["spec"].pop("halt", None)
        else:
            self.system["spec"]["halt"] = halt

    def list_namespaced_custom_object(self, *address: str, label_selector: str) -> dict[str, Any]:
        halt = self.system["spec"].get("halt")
        items = []
        for robot in ("r1", "r2"):
            if f"coral.dev/robot={robot}" not in label_selector and "coral.dev/robot=" in label_selector:
                continue
            asked = halt is not None and (not halt.get("robots") or robot in halt["robots"])
            spec = {"robot": robot, **({"halt": {}} if asked else {})}
            done = asked if robot in self.acknowledging else not asked
            status = {"tree": {"halted": {"since": "2026-01-01T00:00:00Z"}} if done else {}}
            items.append({"spec": spec, "status": status})
        return {"items": items}


@pytest.fixture
def api(monkeypatch: pytest.MonkeyPatch) -> _Api:
    fake = _Api()

    def control(cls: type, namespace: str) -> halt_control.HaltControl:
        made = halt_control.HaltControl.__new__(halt_control.HaltControl)
        made.custom, made.namespace = fake, namespace
        return made

    monkeypatch.setattr(halt_control.HaltControl, "from_kubeconfig", classmethod(control))
    return fake


def test_halt_then_resume_one_robot_sets_and_clears_spec_halt(api: _Api) -> None:
    result = CliRunner().invoke(halt_command, ["mission", "--robot", "r1", "--park-tree", "GoHome"])
    assert result.exit_code == 0, result.output
    assert api.system["spec"]["halt"] == {"robots": ["r1"], "parkTree": "GoHome", "parkTimeoutSeconds": 30}
    assert "halted: r1" in result.output
    result = CliRunner().invoke(resume_command, ["mission", "--robot", "r1"])
    assert result.exit_code == 0, result.output
    assert "halt" not in api.system["spec"]
    assert api.patches[-1]["spec"] == {"halt": None}, "a merge patch's null removes the field"


def test_a_halt_written_at_the_same_time_by_someone_else_is_kept(api: _Api) -> None:
    api.system["spec"]["halt"] = {"robots": ["r2"]}
    api.conflicts = 1
    result = CliRunner().invoke(halt_command, ["mission", "--robot", "r1"])
    assert result.exit_code == 0, result.output
    assert len(api.patches) == 2 and api.system["spec"]["halt"]["robots"] == ["r1", "r2"]


def test_wait_returns_once_every_robot_acknowledged(api: _Api) -> None:
    result = CliRunner().invoke(halt_command, ["mission", "--wait", "--timeout", "5"])
    assert result.exit_code == 0, result.output
    assert "acknowledged by every robot" in result.output


def test_wait_names_the_robots_that_did_not_acknowledge_in_time(api: _Api) -> None:
    api.acknowledging = ("r1",)
    result = CliRunner().invoke(halt_command, ["mission", "--wait", "--timeout", "0.5"])
    assert result.exit_code == 1
    assert "not acknowledged within 0.5 s by r2" in result.output


def test_a_system_that_does_not_exist_is_named(api: _Api) -> None:
    result = CliRunner().invoke(resume_command, ["patrol", "-n", "fleet"])
    assert result.exit_code == 1 and "coralsystem/patrol not found in namespace fleet" in result.output
