"""200 CoralSystems at their admitted maximum keep the operator under its limit and a newcomer served.

Issue 47, acceptance 2: 200 systems with parameters, tree and tree files at their admitted
maximum (about a megabyte each), 20 in each of 10 namespaces, do not take the operator past the
chart's memory limit (a memory cgroup, as in its pod), and a new system in another namespace is
served within 5 s: its first status (`observedGeneration` of its spec) written, and its robot's
CoralInstance created. The systems match no robot: what a robot adds is bounded per robot
(`planning.budgets`) and measured in test_hostile_memory.py.

Half the systems are there before the operator starts, as after a restart: listed as pages of 50
in every namespace at once, those alone OOM-killed it within seconds of its start; its watches
now start with them one event at a time (`kube.watchlist`).
"""

from __future__ import annotations

import os
import time
import uuid
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest
from coral_api import Coral, fleet_mission
from coral_testbed.cluster import memorycgroup
from coral_testbed.waiting import wait_for
from fixtures.cluster import create_test_namespace
from fixtures.confined import ConfinedOperator
from kubernetes import client as k8s
from maximal import maximal_system

pytestmark = [
    pytest.mark.cluster,
    pytest.mark.slow,
    pytest.mark.skipif(memorycgroup.available() is not None, reason=str(memorycgroup.available())),
]

NAMESPACES = 10
SYSTEMS_PER_NAMESPACE = 20
SERVED_WITHIN_S = 5.0
MiB = 1024 * 1024


@pytest.fixture
def load_namespaces(cluster: Any) -> Iterator[list[str]]:
    """Ten namespaces for the load and one elsewhere (last), deleted at teardown."""
    core = k8s.CoreV1Api(cluster.api_client)
    made = [create_test_namespace(core, f"load-{i}") for i in range(NAMESPACES)]
    made.append(create_test_namespace(core, "load-elsewhere"))
    yield made
    for name in made:
        core.delete_namespace(name)


def _cpu_share(pid: int, window_s: float = 2.0) -> float:
    """The share of one CPU the process used over the next `window_s` seconds."""

    def cpu() -> float:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    before = cpu()
    time.sleep(window_s)
    return (cpu() - before) / window_s


def _create(cluster: Any, keys: list[tuple[str, str]]) -> None:
    """Maximal systems at `keys` (namespace, name), four requests at a time."""
    with ThreadPoolExecutor(4) as pool:
        list(
            pool.map(
                lambda key: Coral(cluster.api_client, key[0]).create_system(
                    maximal_system(key[1], "nobody", salt=key[0])
                ),
                keys,
            )
        )


def _with_status(cluster: Any, namespace: str) -> list[str]:
    """The systems of `namespace` whose status the operator wrote: from the API server's table of
    printer columns, not the megabyte objects themselves."""
    header, *rows = cluster.kubectl("get", "coralsystems", "-n", namespace).stdout.splitlines()
    status = header.split().index("STATUS")
    return [row.split()[0] for row in rows if row.split()[status] != "<none>"]


def test_two_hundred_maximal_systems_leave_room_and_time_for_a_new_one(
    cluster: Any,
    coral_crds: None,
    load_namespaces: list[str],
    robots: Callable[..., list[str]],
    tmp_path: Any,
) -> None:
    *loaded, elsewhere = load_namespaces
    fleet = f"f{uuid.uuid4().hex[:8]}"
    robots(1, {"fleet": fleet})
    wanted = [(ns, f"max-{i}") for ns in loaded for i in range(SYSTEMS_PER_NAMESPACE)]
    # Half the load is there before the operator starts, as after a restart: its first listing
    # brings a hundred megabyte objects at once; the other half comes while it serves.
    before, after = wanted[::2], wanted[1::2]
    started = time.monotonic()
    _create(cluster, before)
    operator = ConfinedOperator.start(
        cluster,
        load_namespaces,
        tmp_path / "operator.log",
        {
            "CORAL_POLICY_HOST_NETWORK_NAMESPACES": ",".join(load_namespaces),
            # The newcomer is the fleet example, whose bag player reads the robot's bags.
            "CORAL_POLICY_HOST_PATHS": f"{elsewhere}=/var/lib/coral/bags",
        },
    )
    try:
        _create(cluster, after)
        created_s = time.monotonic() - started
        left = set(wanted)

        def all_served() -> bool:
            # An operator killed under the load would leave the rest unserved for the whole wait.
            operator.assert_alive()
            for namespace in {namespace for namespace, _ in left}:
                left.difference_update((namespace, name) for name in _with_status(cluster, namespace))
            return not left

        wait_for(
            all_served,
            timeout=240,
            interval=2,
            message=lambda: (
                f"{len(left)} of 200 systems still unserved; operator log:\n{operator.logs()[-3000:]}"
            ),
        )
        served_s = time.monotonic() - started
        # Served is not idle: the watch still brings every system's status write back (a megabyte
        # each). The newcomer is timed once the operator has digested the load.
        wait_for(
            lambda: _cpu_share(operator.process.pid) < 0.1,
            timeout=180,
            interval=0,
            message="the operator to be idle after the load",
        )
        settled_s = time.monotonic() - started
        loaded_peak = operator.cgroup.peak_bytes()

        coral = Coral(cluster.api_client, elsewhere)
        asked = time.monotonic()
        coral.create_system(fleet_mission("newcomer", fleet))
        wait_for(
            lambda: coral.served("newcomer"),
            timeout=60,
            interval=0.1,
            message=lambda: (
                f"the newcomer's first status ({'; '.join(operator.problems()) or 'operator alive'}); "
                f"operator log:\n{operator.logs()[-3000:]}"
            ),
        )
        first_status_s = time.monotonic() - asked
        wait_for(lambda: coral.instances(), timeout=60, interval=0.1, message="the newcomer's CoralInstance")
        instance_s = time.monotonic() - asked
        print(
            f"\n200 maximal systems created in {created_s:.0f} s, all served after {served_s:.0f} s, "
            f"operator idle after {settled_s:.0f} s; "
            f"operator peak {loaded_peak / MiB:.0f} MiB of {operator.cgroup.limit_bytes / MiB:.0f} MiB "
            f"(now {operator.cgroup.usage_bytes() / MiB:.0f} MiB, "
            f"heap {operator.cgroup.rss_bytes() / MiB:.0f} MiB); "
            f"newcomer's first status after {first_status_s:.2f} s, its instance after {instance_s:.2f} s"
        )
        assert first_status_s < SERVED_WITHIN_S
        assert instance_s < SERVED_WITHIN_S
        operator.assert_serving()
    finally:
        operator.stop()
