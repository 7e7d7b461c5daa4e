"""Acceptance 4: an operator killed mid-rollout and started again resumes without ever exceeding
`maxUnavailable`; `coral rollout undo` returns every robot to the previous revision."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import pytest
from click.testing import CliRunner
from coral_operator.rollout_cli import rollout
from coral_testbed.waiting import wait_for
from fleet import Fleet, instance_ready, mission, rolled_back_and_ready, wait_settled

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

ROBOTS = 8
MAX_UNAVAILABLE = 2


class UnavailableSampler:
    """Counts robots whose instance is not Ready, from outside, every few hundred milliseconds."""

    def __init__(self, fleet: Fleet) -> None:
        self.fleet = fleet
        self.peak = 0
        self.samples = 0
        self.phase = "update"
        self.worst: dict[str, int] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self._stop.wait(0.3):
            instances = self.fleet.instances()
            unavailable = sum(1 for i in instances.values() if not instance_ready(i))
            self.peak = max(self.peak, unavailable)
            self.worst[self.phase] = max(self.worst.get(self.phase, 0), unavailable)
            self.samples += 1

    def __enter__(self) -> UnavailableSampler:
        self._thread.start()
        return self

    def __exit__(self, *_: Any) -> None:
        self._stop.set()
        self._thread.join(timeout=10)


def test_a_killed_operator_resumes_within_max_unavailable_and_undo_returns_every_robot(
    cluster: Any, namespace: str, operator: Any, robots: Callable[..., list[str]], fleet_label: str
) -> None:
    names = robots(ROBOTS, {"fleet": fleet_label})
    fleet = Fleet(cluster.api_client, namespace, "patrol")
    fleet.create(mission("patrol", fleet_label, {"maxUnavailable": MAX_UNAVAILABLE}))
    wait_settled(fleet, ROBOTS)
    first = fleet.revisions()[names[0]]

    with UnavailableSampler(fleet) as sampler:
        fleet.change("2")
        wait_for(
            lambda: 1 <= sum(r != first for r in fleet.revisions().values()) < ROBOTS,
            timeout=90,
            interval=0.1,
            message="the rollout to be under way",
        )
        operator.kill()
        sampler.phase = "restart"
        moved_while_down = sum(r != first for r in fleet.revisions().values())
        operator.start()
        wait_settled(fleet, ROBOTS, timeout=180)
        second = fleet.revisions()[names[0]]
        assert set(fleet.revisions().values()) == {second} != {first}
        assert moved_while_down < ROBOTS

        sampler.phase = "undo"
        runner = CliRunner(env={"KUBECONFIG": str(cluster.kubeconfig)})
        result = runner.invoke(rollout, ["undo", "patrol", "-n", namespace])
        assert result.exit_code == 0, result.output
        assert second in result.output
        wait_for(
            lambda: set(fleet.revisions().values()) == {first},
            timeout=180,
            message=lambda: f"every robot back on {first}: {fleet.revisions()}",
        )
        # Every robot Ready on the revision returned to, and the system honest about it: it does
        # not run its spec's revision, so it is Stalled (RolledBack) until the spec changes.
        wait_for(
            lambda: rolled_back_and_ready(fleet, ROBOTS),
            timeout=120,
            message=lambda: f"{ROBOTS} robots ready after the undo; rollout={fleet.rollout()}",
        )

    assert sampler.samples > 10
    assert sampler.peak <= MAX_UNAVAILABLE, f"robots unavailable at once, by phase: {sampler.worst}"
    rolled = fleet.rollout()["rolledBack"]
    assert rolled == {"fromRevision": second, "toRevision": first, "reason": "Undo"}
    status = runner.invoke(rollout, ["status", "patrol", "-n", namespace])
    assert status.exit_code == 1 and f"rolled back from {second} to {first}" in status.output
    assert "Traceback" not in operator.logs()
