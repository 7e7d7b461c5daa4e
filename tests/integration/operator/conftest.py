"""Fixtures of the operator's integration tests: CRDs installed, the operator running, robots.

Each test gets its own namespace (fixture `namespace`), its own operator process serving only that
namespace, and robots with unique names and a unique fleet label, removed at teardown.
"""

from __future__ import annotations

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
def coral_crds(cluster: Any) -> None:
    """The coral.dev CRDs applied and established."""
    cluster.kubectl("apply", "--server-side", "--force-conflicts", "-f", str(ROOT / "crds"))
    for name in ("coralsystems.coral.dev", "coralinstances.coral.dev"):
        # `kubectl wait` fails outright while a new CRD has no status yet; poll instead.
        wait_for(
            lambda name=name: (
                # check=False: a CRD that has no conditions yet makes this jsonpath fail.
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


class OperatorProcess:
    """The operator as a subprocess serving one namespace; restartable."""

    def __init__(
        self, cluster: Any, namespace: str, log_dir: Path, extra_env: dict[str, str] | None = None
    ) -> None:
        self.cluster = cluster
        self.extra_env = extra_env or {}
        self.namespace = namespace
        self.log_dir = log_dir
        self.process: subprocess.Popen[Any] | None = None
        self.starts = 0

    def start(self) -> None:
        self.starts += 1
        log = (self.log_dir / f"operator-{self.starts}.log").open("w")
        env = {**self.cluster.env(), "PYTHONUNBUFFERED": "1", **self.extra_env}
        self.process = subprocess.Popen(
            [sys.executable, "-m", "coral_operator", "-n", self.namespace],
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )

    def stop(self) -> None:
        if self.process is not None:
            stop_process_group(self.process, timeout=15)
            self.process = None

    def log(self) -> str:
        return (self.log_dir / f"operator-{self.starts}.log").read_text()


@pytest.fixture
def operator_env() -> dict[str, str]:
    """Extra environment of the operator process; a test module overrides it to configure the operator."""
    return {}


@pytest.fixture
def coral_operator(
    cluster: Any, namespace: str, coral_crds: None, tmp_path: Path, operator_env: dict[str, str]
) -> Iterator[OperatorProcess]:
    """The operator running against the test's namespace, stopped at teardown."""
    process = OperatorProcess(cluster, namespace, tmp_path, operator_env)
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
    """A label value no other test uses, for this test's robot selector."""
    return f"f{uuid.uuid4().hex[:8]}"


@pytest.fixture
def wait() -> Callable[..., Any]:
    """`wait_for` with the operator tests' default timeout."""

    def waiting(predicate: Callable[[], Any], message: str | Callable[[], str], timeout: float = 90) -> Any:
        return wait_for(predicate, timeout=timeout, interval=0.3, message=message)

    return waiting
