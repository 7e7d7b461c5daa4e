"""`coral logs SYSTEM`: which containers are a system's components, how their lines are prefixed
(coloured on a terminal, plain in a pipe), `--since`, and lines kept whole and in order as a
followed log arrives in pieces."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import click
import pytest
from coral_core import names
from coral_operator import fleet_logs
from coral_operator.planning.pods import FOLDERS_OWNER


def _status(name: str, state: str, container_id: str = "") -> dict[str, Any]:
    return {"name": name, "state": {state: {}}, "containerID": container_id or f"containerd://{name}"}


def _pod(
    name: str, robot: str, containers: list[str], sidecars: tuple[str, ...] = (), **states: str
) -> dict[str, Any]:
    """A pod of the system on `robot`; every container running unless `states` says otherwise."""
    inits = [{"name": FOLDERS_OWNER}, *({"name": s, "restartPolicy": "Always"} for s in sidecars)]
    return {
        "metadata": {"name": name, "labels": {names.LABEL_ROBOT: robot}},
        "spec": {"nodeName": robot, "initContainers": inits, "containers": [{"name": c} for c in containers]},
        "status": {
            "initContainerStatuses": [
                _status(FOLDERS_OWNER, "terminated"),
                *(_status(s, states.get(s, "running")) for s in sidecars),
            ],
            "containerStatuses": [_status(c, states.get(c, "running")) for c in containers],
        },
    }


def test_every_started_component_container_is_a_stream_and_the_folder_helper_is_not() -> None:
    pods = [
        _pod("r2-robot", "r2", ["executor"], sidecars=("lidar", "slam")),
        _pod("r1-slam", "r1", ["slam"]),
        _pod("r1-executor", "r1", ["executor"]),
    ]
    found = [(s.robot, s.component, s.pod) for s in fleet_logs.streams_of(pods, None)]
    assert found == [
        ("r1", "executor", "r1-executor"),
        ("r1", "slam", "r1-slam"),
        ("r2", "executor", "r2-robot"),
        ("r2", "lidar", "r2-robot"),
        ("r2", "slam", "r2-robot"),
    ]


def test_a_container_that_has_not_started_has_no_log_to_read_yet() -> None:
    pods = [_pod("r1-robot", "r1", ["executor"], sidecars=("slam",), executor="waiting")]
    assert [s.component for s in fleet_logs.streams_of(pods, None)] == ["slam"]


def test_component_filter_keeps_that_component_on_every_robot() -> None:
    pods = [_pod("r1-robot", "r1", ["executor"], sidecars=("slam",)), _pod("r2-slam", "r2", ["slam"])]
    assert [(s.robot, s.pod) for s in fleet_logs.streams_of(pods, "slam")] == [
        ("r1", "r1-robot"),
        ("r2", "r2-slam"),
    ]


def test_a_restarted_container_is_a_new_stream() -> None:
    before = fleet_logs.streams_of([_pod("r1-slam", "r1", ["slam"])], None)
    after_pod = _pod("r1-slam", "r1", ["slam"])
    after_pod["status"]["containerStatuses"][0]["containerID"] = "containerd://second"
    after = fleet_logs.streams_of([after_pod], None)
    assert before != after and (before[0].pod, before[0].container) == (after[0].pod, after[0].container)


STREAM = fleet_logs.Stream("r1-slam-abc", "slam", "r1", "slam", "containerd://1")


def test_in_a_pipe_the_prefix_is_plain_text_padded_to_the_widest_prefix() -> None:
    assert (
        fleet_logs.prefixed(STREAM, "map updated", width=14, colour=False) == "r1/slam        | map updated"
    )
    assert "\x1b" not in fleet_logs.prefixed(STREAM, "x", width=0, colour=False)


def test_on_a_terminal_robot_and_component_are_coloured_and_the_line_is_not() -> None:
    line = fleet_logs.prefixed(STREAM, "map updated", width=14, colour=True)
    assert click.unstyle(line) == "r1/slam        | map updated"
    robot, component = (
        click.style("r1", fg=fleet_logs.colour_of("r1"), bold=True),
        click.style("slam", fg=fleet_logs.colour_of("slam")),
    )
    assert line.startswith(f"{robot}/{component}") and line.endswith("| map updated")


def test_a_robot_keeps_its_colour_from_run_to_run() -> None:
    # crc32, not hash(): Python salts str hashes per process.
    assert fleet_logs.colour_of("r1") == fleet_logs.colour_of("r1") in fleet_logs.PALETTE
    assert len({fleet_logs.colour_of(f"r{i}") for i in range(20)}) > 1


@pytest.mark.parametrize(
    ("text", "seconds"), [("30s", 30), ("5m", 300), ("1h30m", 5400), ("2d", 172800), ("90s", 90)]
)
def test_since_reads_durations_as_kubectl_writes_them(text: str, seconds: int) -> None:
    assert fleet_logs.parse_since(text) == seconds


@pytest.mark.parametrize("text", ["", "5", "5x", "m5", "1h 30m", "-5m", "0s"])
def test_since_refuses_what_is_not_a_duration(text: str) -> None:
    with pytest.raises(ValueError, match=repr(text)):
        fleet_logs.parse_since(text)


class _Chunks:
    """A streamed log response as the API server sends it: in chunks that cut lines anywhere."""

    def __init__(self, *chunks: bytes) -> None:
        self.chunks = chunks

    def stream(self, amt: int, decode_content: bool) -> Iterator[bytes]:
        yield from self.chunks


def test_lines_cut_across_chunks_come_out_whole_and_in_order() -> None:
    response = _Chunks(b"tick 1\ntick", b" 2\r\n", b"", b"tick 3\nti", b"ck 4\nunfinished")
    assert list(fleet_logs.lines_of(response)) == ["tick 1", "tick 2", "tick 3", "tick 4", "unfinished"]


def test_bytes_that_are_not_utf8_do_not_end_the_stream() -> None:
    assert list(fleet_logs.lines_of(_Chunks(b"ok\n\xff\xfe bad\nafter\n"))) == [
        "ok",
        "\ufffd\ufffd bad",
        "after",
    ]
