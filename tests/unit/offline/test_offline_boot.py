"""The agent at a boot without the API server: the checked copy runs, an altered one is refused."""

from __future__ import annotations

import fcntl
import json
import socket
from pathlib import Path

import pytest
import yaml
from coral.offline import store
from coral.offline.agent import Agent, report_message, summarize_run
from coral.offline.staticpods import part_of, static_copy
from coral_core import names, offline
from offline_pods import CONFIG_MAPS, robot_pods, system


@pytest.fixture
def agent(tmp_path: Path) -> Agent:
    # A port nobody listens on: the API server is out of reach, as on a robot cut off.
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    kubeconfig = tmp_path / "kubeconfig"
    kubeconfig.write_text(
        yaml.safe_dump(
            {
                "apiVersion": "v1",
                "kind": "Config",
                "clusters": [{"name": "c", "cluster": {"server": f"https://127.0.0.1:{port}"}}],
                "users": [{"name": "u", "user": {"token": "t"}}],
                "contexts": [{"name": "x", "context": {"cluster": "c", "user": "u"}}],
                "current-context": "x",
            }
        )
    )
    return Agent(robot="r1", kubeconfig=kubeconfig, root=tmp_path / "offline", static_dir=tmp_path / "static")


def _record(agent: Agent) -> list[dict]:
    pods = robot_pods(system(offline={"mode": "LastRevision"}))
    copies = [
        static_copy(p, config_maps=CONFIG_MAPS, files_dir="/f/" + part_of(p), run_dir="/r") for p in pods
    ]
    files = {f"{part_of(p)}/{k}": v for p, c in zip(pods, copies, strict=True) for k, v in c.files.items()}
    labels = pods[0]["metadata"]["labels"]
    manifest = offline.CacheManifest(
        namespace="ns",
        system="sys",
        instance="sys-r1",
        instance_uid="uid-1",
        robot="r1",
        revision=labels[names.LABEL_REVISION],
        recorded_at="2026-01-01T00:00:00Z",
        interrupt_running_trees=False,
        pods=[c.pod for c in copies],
        files={k: offline.file_digest(v) for k, v in files.items()},
        images={},
    )
    store.write_cache(agent.root / "systems" / "ns_sys", manifest, files, store.robot_key(agent.root), "s")
    return [c.pod for c in copies]


def test_a_checked_copy_becomes_static_pods(agent: Agent) -> None:
    expected = _record(agent)
    report = agent.boot()
    assert report["apiReachable"] is False
    assert report["systems"]["ns_sys"]["action"] == "RunOffline"
    written = sorted(agent.static_dir.iterdir())
    assert [json.loads(p.read_text()) for p in written] == expected
    assert (agent.root / "runs" / "ns_sys").is_dir()


def test_an_altered_copy_is_refused_and_nothing_runs(agent: Agent) -> None:
    _record(agent)
    tree = agent.root / "systems/ns_sys/files/executor/config/tree.xml"
    tree.write_text(tree.read_text().replace("AlwaysSuccess", "AlwaysFailure"))
    report = agent.boot()
    entry = report["systems"]["ns_sys"]
    assert entry["action"] == "Refused"
    assert "executor/config/tree.xml was altered" in entry["reason"]
    assert list(agent.static_dir.iterdir()) == []
    kind, reason, message = report_message(entry)
    assert (kind, reason) == ("Warning", "OfflineCacheRefused")
    assert "tree.xml was altered" in message


def test_a_robot_never_given_a_revision_runs_nothing_and_says_so(agent: Agent) -> None:
    report = agent.boot()
    assert report["systems"] == {"": {**report["systems"][""], "action": "NoRevision"}}
    assert list(agent.static_dir.iterdir()) == []
    assert report_message(report["systems"][""])[1] == "NoRevisionOffline"


def test_a_copy_left_by_an_earlier_boot_is_not_reused_unchecked(agent: Agent) -> None:
    agent.static_dir.mkdir(parents=True)
    (agent.static_dir / f"{offline.STATIC_POD_PREFIX}ns_other+0.json").write_text("{}")
    (agent.static_dir / "someone-elses.yaml").write_text("{}")
    agent.boot()
    assert [p.name for p in agent.static_dir.iterdir()] == ["someone-elses.yaml"]


def test_the_report_tells_how_far_the_offline_tree_got() -> None:
    lines = [
        json.dumps({"event": "waiting", "ts": 1.0}),
        json.dumps({"event": "status", "ts": 2.0, "root_status": "RUNNING", "tick_count": 1}),
        "half a line",
        json.dumps(
            {"event": "status", "ts": 9.0, "root_status": "RUNNING", "tick_count": 70, "active_path": "a/b"}
        ),
    ]
    run = summarize_run(lines)
    assert run == {
        "ticked": True,
        "rootStatus": "RUNNING",
        "tickCount": 70,
        "activePath": "a/b",
        "firstStatusAt": 2.0,
        "lastStatusAt": 9.0,
    }
    entry = {"action": "RunOffline", "bootedAt": "T0", "revision": "abc", "run": run, "handedOverAt": "T1"}
    assert "RUNNING at tick 70" in report_message(entry)[2]
    assert summarize_run([]) == {"ticked": False}


def test_the_offline_copy_stays_while_cut_off_and_its_tree_runs_while_its_lock_is_held(agent: Agent) -> None:
    _record(agent)
    agent.boot()
    written = sorted(agent.static_dir.iterdir())
    agent.step(record=False)
    assert sorted(agent.static_dir.iterdir()) == written, "the copy went away with no API server to take over"
    lock = agent.root / "locks" / offline.lock_name("ns", "sys", "executor")
    lock.parent.mkdir(parents=True, exist_ok=True)
    assert not agent.tree_running("ns_sys")
    # The executor's lock holder, as the kernel sees it: another open file holding the lock.
    with lock.open("a") as holder:
        fcntl.flock(holder, fcntl.LOCK_EX)
        assert agent.tree_running("ns_sys")
    assert not agent.tree_running("ns_sys")
