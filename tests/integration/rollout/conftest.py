"""Fixtures of the rollout integration tests: CRDs, the operator as a restartable subprocess, robots.

Each test gets its own namespace, its own operator process serving only that namespace, and kwok
robots with unique names and a unique fleet label, removed at teardown.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from coral_testbed.waiting import wait_for
from fixtures.processes import stop_process_group

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="session")
def rollout_crds(cluster: Any) -> None:
    """The coral.dev CRDs (with `status.rollout`) applied and established."""
    cluster.kubectl("apply", "--server-side", "--force-conflicts", "-f", str(ROOT / "crds"))
    for name in ("coralsystems.coral.dev", "coralinstances.coral.dev"):
        wait_for(
            lambda name=name: (
                cluster.kubectl(
                    "get",
                    "crd",
                    name,
                    "-o",
                    'jsonpath={.status.conditions[?(@.type=="Established")].status}',
                    check=False,
                ).stdout
                == "True"
            ),
            timeout=60,
            message=f"CRD {name} to be Established",
        )


class Operator:
    """`python -m coral_operator -n <namespace>`, startable again after being killed."""

    def __init__(self, cluster: Any, namespace: str, log_dir: Path) -> None:
        self.cluster = cluster
        self.namespace = namespace
        self.log_dir = log_dir
        self.process: subprocess.Popen[Any] | None = None
        self.starts = 0

    def start(self) -> None:
        self.starts += 1
        log = (self.log_dir / f"operator-{self.starts}.log").open("w")
        self.process = subprocess.Popen(
            [sys.executable, "-m", "coral_operator", "-n", self.namespace],
            env={**self.cluster.env(), "PYTHONUNBUFFERED": "1"},
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )

    def kill(self) -> None:
        """SIGKILL, as a crash or an evicted pod would end it: no clean shutdown."""
        assert self.process is not None
        os.killpg(self.process.pid, signal.SIGKILL)
        self.process.wait(timeout=15)
        self.process = None

    def stop(self) -> None:
        if self.process is not None:
            stop_process_group(self.process, timeout=15)
            self.process = None

    def logs(self) -> str:
        return "\n".join((self.log_dir / f"operator-{i}.log").read_text() for i in range(1, self.starts + 1))


@pytest.fixture
def operator(cluster: Any, namespace: str, rollout_crds: None, tmp_path: Path) -> Iterator[Operator]:
    process = Operator(cluster, namespace, tmp_path)
    process.start()
    try:
        yield process
    finally:
        process.stop()


@pytest.fixture
def robots(cluster: Any) -> Iterator[Callable[..., list[str]]]:
    """Factory creating kwok robots with unique names; every robot is removed at teardown."""
    made: list[str] = []
    tag = uuid.uuid4().hex[:5]

    def create(count: int, labels: dict[str, str] | None = None, start: int = 1) -> list[str]:
        names = [f"r{tag}-{i}" for i in range(start, start + count)]
        cluster.add_robots(names, labels)
        made.extend(names)
        return names

    yield create
    if made:
        cluster.remove_robots(made)


@pytest.fixture
def fleet_label() -> str:
    return f"f{uuid.uuid4().hex[:8]}"
