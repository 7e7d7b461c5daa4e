"""The executor's Kubernetes sink patches the instance's status on change, rate limited, and gets the
last one through an API server that stalls or refuses for a while."""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import pytest
from coral.executor import kubernetes_sink as sink
from coral_core.instance_status import CoralInstanceStatus
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _status(root: str, tick: int, active: str = "") -> dict[str, Any]:
    return {"event": "status", "root_status": root, "tick_count": tick, "active_path": active}


def _sink(patches: list[dict[str, Any]], clock: Clock) -> sink.KubernetesStatusSink:
    return sink.KubernetesStatusSink(
        patches.append, min_interval_s=1.0, clock=clock, wall=lambda: 0.0, background=False
    )


def test_a_status_record_becomes_the_tree_summary() -> None:
    state = sink.summarize(
        CoralInstanceStatus(),
        {
            "event": "status",
            "root_status": "RUNNING",
            "tick_count": 12,
            "active_path": "Main/Seq/Move",
            "last_failure": {"path": "Main/Seq/Check", "message": "no scan", "time": 0.0},
            "conditions": [{"type": "LibraryDegraded", "status": "True", "message": "slam died"}],
        },
    ).to_patch()
    assert state["tree"] == {
        "rootStatus": "RUNNING",
        "tickCount": 12,
        "activePath": "Main/Seq/Move",
        "lastFailure": {"path": "Main/Seq/Check", "message": "no scan", "time": "1970-01-01T00:00:00Z"},
        "message": "",
    }
    assert state["plugins"]["degraded"] == ["slam died"]


def test_waiting_and_plugin_records_fill_the_plugin_summary() -> None:
    state = sink.summarize(CoralInstanceStatus(), {"event": "waiting", "missing": ["EstimatePose"]})
    state = sink.summarize(
        state,
        {
            "event": "plugins",
            "loaded": [{"component": "slam", "behaviors": ["EstimatePose"]}],
            "conflicts": [],
            "refused": [],
        },
    )
    state = sink.summarize(state, {"event": "condition", "type": "PluginsReady", "status": "True"}).to_patch()
    assert state["plugins"] == {"missing": [], "loaded": ["slam"], "conflicts": []}
    assert state["tree"]["message"] == "Waiting for node types: EstimatePose"


def test_transitions_alone_change_nothing() -> None:
    assert sink.summarize(CoralInstanceStatus(), {"event": "transition", "path": "a"}).to_patch() == {}


def test_it_patches_on_change_only_and_at_most_once_per_interval() -> None:
    patches: list[dict[str, Any]] = []
    clock = Clock()
    status_sink = _sink(patches, clock)
    status_sink.emit(_status("RUNNING", 1))
    assert len(patches) == 1 and patches[0]["status"]["tree"]["tickCount"] == 1
    status_sink.emit(_status("RUNNING", 2))
    assert len(patches) == 1, "a second change within the interval waits"
    clock.now += 1.5
    status_sink.emit(_status("RUNNING", 2))
    assert len(patches) == 2 and patches[1]["status"]["tree"]["tickCount"] == 2
    clock.now += 5
    status_sink.emit(_status("RUNNING", 2))
    assert len(patches) == 2, "an unchanged summary is not written again"


def test_a_halt_acknowledgement_is_written_at_once_despite_the_interval() -> None:
    """`coral halt --wait` waits on it: the rate limit must not add up to a second to a halt."""
    patches: list[dict[str, Any]] = []
    clock = Clock()
    status_sink = _sink(patches, clock)
    status_sink.emit(_status("RUNNING", 1))
    status_sink.emit({"event": "halted", "since": 0.0, "park_tree": None, "park_status": None})
    assert len(patches) == 2 and patches[1]["status"]["tree"]["halted"] == {"since": "1970-01-01T00:00:00Z"}
    status_sink.emit(_status("IDLE", 1))
    assert len(patches) == 2, "what follows the acknowledgement waits for the interval again"
    status_sink.emit({"event": "resumed"})
    assert len(patches) == 3 and patches[2]["status"]["tree"]["halted"] is None


def test_close_flushes_the_last_pending_summary() -> None:
    patches: list[dict[str, Any]] = []
    status_sink = _sink(patches, Clock())
    status_sink.emit(_status("RUNNING", 1))
    status_sink.emit(_status("SUCCESS", 9))
    status_sink.close()
    assert patches[-1]["status"]["tree"]["rootStatus"] == "SUCCESS"


def test_a_failing_patch_never_raises_into_the_executor() -> None:
    def refuse(_: dict[str, Any]) -> None:
        raise RuntimeError("forbidden")

    status_sink = sink.KubernetesStatusSink(refuse, clock=Clock(), background=False)
    status_sink.emit(_status("RUNNING", 1))
    assert status_sink.patches == 0


class ApiServerStandIn:
    """A real HTTP server on 127.0.0.1 that answers each status patch as scripted: "stall" (reads
    the request and never answers, as over a link that died mid-request), an HTTP status code, or
    "ok" once the script runs out. It records every patch body it accepted."""

    def __init__(self, script: list[str | int]) -> None:
        self.script = list(script)
        self.accepted: list[dict[str, Any]] = []
        self.requests = 0
        self.release = threading.Event()
        stand_in = self

        class Handler(BaseHTTPRequestHandler):
            def do_PATCH(self) -> None:  # noqa: N802 - the http.server hook's name
                body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
                stand_in.requests += 1
                answer = stand_in.script.pop(0) if stand_in.script else "ok"
                if answer == "stall":
                    stand_in.release.wait(timeout=30)
                    self.close_connection = True
                    return
                code = 200 if answer == "ok" else int(answer)
                if code == 200:
                    stand_in.accepted.append(body)
                payload = b"{}"
                self.send_response(code)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(payload)))
                self.end_headers()
                self.wfile.write(payload)

            def log_message(self, *_: Any) -> None:
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.server.daemon_threads = True
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def patcher(self, timeout: tuple[float, float]) -> sink.Patcher:
        configuration = k8s.Configuration()
        configuration.host = f"http://127.0.0.1:{self.server.server_address[1]}"
        return sink.build_patcher(k8s.ApiClient(configuration), "fleet", "patrol-r1", timeout=timeout)

    def last_tree(self) -> dict[str, Any]:
        return self.accepted[-1]["status"]["tree"] if self.accepted else {}

    def stop(self) -> None:
        self.release.set()
        self.server.shutdown()
        self.server.server_close()


@pytest.fixture
def stand_in(request: pytest.FixtureRequest) -> Iterator[ApiServerStandIn]:
    server = ApiServerStandIn(request.param)
    yield server
    server.stop()


def _ended(
    stand_in: ApiServerStandIn,
    root: str,
    exit_code: int,
    *,
    timeout: tuple[float, float],
    close_grace_s: float,
    finished_grace_s: float,
) -> sink.KubernetesStatusSink:
    """A sink whose tree has ended with `root` and the executor's `exit_code`, not yet closed."""
    status_sink = sink.KubernetesStatusSink(
        stand_in.patcher(timeout=timeout),
        min_interval_s=0.05,
        close_grace_s=close_grace_s,
        finished_grace_s=finished_grace_s,
    )
    status_sink.emit(_status(root, 4))
    status_sink.emit({"event": "finished", "root_status": root, "exit_code": exit_code, "tick_count": 4})
    return status_sink


@pytest.mark.parametrize("stand_in", [["stall"]], indirect=True)
def test_a_stalled_patch_is_given_up_and_the_finished_tree_still_reaches_its_instance(
    stand_in: ApiServerStandIn,
) -> None:
    status_sink = sink.KubernetesStatusSink(stand_in.patcher(timeout=(1.0, 0.5)), min_interval_s=0.05)
    try:
        started = time.monotonic()
        status_sink.emit(_status("RUNNING", 1))
        assert time.monotonic() - started < 0.1, "the tick thread must not wait on the API server"
        wait_for(lambda: stand_in.requests == 1, timeout=5, message="the first patch to reach the server")
        status_sink.emit(_status("SUCCESS", 9))
        # No record follows the last one: the sink must retry by itself.
        wait_for(
            lambda: stand_in.last_tree().get("rootStatus") == "SUCCESS",
            timeout=10,
            message=lambda: f"SUCCESS patched after the stall; server saw {stand_in.requests} requests",
        )
    finally:
        status_sink.close()
    assert stand_in.last_tree()["tickCount"] == 9


@pytest.mark.parametrize("stand_in", [[503, 503]], indirect=True)
def test_a_tree_that_ended_by_itself_waits_past_the_signal_grace_for_its_result_to_land(
    stand_in: ApiServerStandIn,
) -> None:
    status_sink = _ended(stand_in, "FAILURE", 1, timeout=(1.0, 1.0), close_grace_s=0.5, finished_grace_s=30)
    status_sink.close()
    # Refused twice, then taken: 1 s and 2 s pauses, more than the 0.5 s a signal would allow.
    assert stand_in.last_tree().get("rootStatus") == "FAILURE", stand_in.requests
    assert stand_in.requests == 3


@pytest.mark.parametrize("stand_in", [["stall"] * 20], indirect=True)
def test_a_tree_stopped_by_a_signal_gives_up_its_last_status_after_the_short_grace(
    stand_in: ApiServerStandIn, caplog: pytest.LogCaptureFixture
) -> None:
    status_sink = _ended(stand_in, "IDLE", 143, timeout=(0.5, 0.3), close_grace_s=1.0, finished_grace_s=60)
    started = time.monotonic()
    with caplog.at_level(logging.WARNING):
        status_sink.close()
    # The grace, plus at most one request's deadline already under way.
    assert time.monotonic() - started < 1.0 + 0.8 + 0.5
    assert stand_in.accepted == [] and status_sink.patches == 0
    assert "last status was not written" in caplog.text


@pytest.mark.parametrize("stand_in", [[404] * 20], indirect=True)
def test_a_last_status_whose_instance_is_gone_is_not_retried(
    stand_in: ApiServerStandIn, caplog: pytest.LogCaptureFixture
) -> None:
    """Deleting a system removes its instances as it stops their executors: waiting out a grace
    period against 404s would only hold each stopping pod."""
    status_sink = _ended(stand_in, "SUCCESS", 0, timeout=(1.0, 1.0), close_grace_s=20, finished_grace_s=60)
    started = time.monotonic()
    with caplog.at_level(logging.WARNING):
        status_sink.close()
    assert time.monotonic() - started < 2.0
    assert stand_in.requests <= 2 and stand_in.accepted == []
    assert "refused it" in caplog.text
