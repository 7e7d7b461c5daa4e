"""`coral rollout status` as a person sees it on a terminal (read through a terminal emulator) while a
robot in mission holds the rollout, and as plain text in a pipe."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from typing import Any

import pytest
from coral_testbed.waiting import wait_for
from fixtures.terminal import run_on_terminal
from fleet import Fleet, mission, wait_settled

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

HEADERS = ["ROBOTS", "UPDATED", "HEALTHY", "UNAVAILABLE", "MAX UNAVAILABLE", "LOCKED", "OFFLINE"]


def _cells(header: str, row: str) -> dict[str, str]:
    """The row's value under each header; the values are right-aligned, so each ends where its
    header ends."""
    cells = {}
    for name in HEADERS:
        end = header.index(name) + len(name)
        cells[name] = row[:end].split()[-1]
    return cells


@pytest.fixture
def held_rollout(
    cluster: Any, namespace: str, operator: Any, robots: Callable[..., list[str]], fleet_label: str
) -> tuple[Fleet, str]:
    """A fleet of two whose new revision reached one robot and waits for the other, in mission."""
    busy, _idle = robots(2, {"fleet": fleet_label})
    fleet = Fleet(cluster.api_client, namespace, "patrol")
    fleet.create(mission("patrol", fleet_label, {"maxUnavailable": "100%"}))
    wait_settled(fleet, 2)
    fleet.set_tree(busy, "RUNNING")
    wait_for(lambda: fleet.system()["status"]["trees"]["running"] == 1, timeout=60, message="RUNNING counted")
    fleet.change("2")
    wait_for(lambda: fleet.rollout().get("waitingFor") == [busy], timeout=90, message="the lock reported")
    wait_for(lambda: fleet.rollout()["counts"]["updated"] == 1, timeout=90, message="the idle robot moved")
    return fleet, busy


def test_a_held_rollout_shows_its_counts_as_a_table_and_what_it_waits_for(
    cluster: Any, namespace: str, held_rollout: tuple[Fleet, str]
) -> None:
    fleet, busy = held_rollout
    argv = [sys.executable, "-m", "coral", "rollout", "status", "patrol", "-n", namespace]
    screen = run_on_terminal(argv, cluster.env())
    assert screen.returncode == 0, screen.text
    lines = [line for line in screen.lines if line]
    revision = fleet.rollout()["revision"]
    assert lines[0].startswith(f"coralsystem/patrol revision {revision} (previous ")
    header = next(line for line in lines if line.split()[:1] == ["ROBOTS"])
    row = lines[lines.index(header) + 1]
    assert header.split() == " ".join(HEADERS).split()
    cells = _cells(header, row)
    assert (cells["ROBOTS"], cells["UPDATED"], cells["LOCKED"]) == ("2", "1", "1"), f"{header}\n{row}"
    assert f"  waiting for: {busy}" in lines
    # Long lines wrap at the terminal's width, as rich wraps them.
    verdict = next(line for line in lines if line.startswith("  in progress, waiting for "))
    assert b"\x1b[1m" in screen.raw  # the title and headers in bold
    assert b"\x1b[33m" in screen.raw  # the verdict in yellow: still in progress

    piped = subprocess.run(argv, env=cluster.env(), capture_output=True, timeout=60, check=True)
    assert b"\x1b" not in piped.stdout
    plain = piped.stdout.decode().splitlines()
    assert [line.split() for line in plain[:4]] == [line.split() for line in lines[:4]]
    assert plain[-1].startswith(verdict)  # one line in a pipe: nothing wraps
