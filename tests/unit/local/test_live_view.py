"""The live tree view folds executor status records; off a terminal it prints plain progress lines."""

from __future__ import annotations

import io
import json
from pathlib import Path

from coral.local.console import Console, StatusTail, TreeView, outline_of
from coral_core import terminal


def _rendered(view: TreeView) -> list[str]:
    """The footer as plain text, as a pipe would receive it."""
    stream = io.StringIO()
    terminal.console(stream, colour=False).print(view.renderable())
    return [line.rstrip() for line in stream.getvalue().splitlines()]


def _records() -> list[dict[str, object]]:
    return [
        {"event": "transition", "path": "Main", "node_id": "Sequence", "status": "RUNNING"},
        {"event": "transition", "path": "Main/ProcessScan", "node_id": "ProcessScan", "status": "RUNNING"},
        {"event": "status", "root_status": "RUNNING", "tick_count": 7, "active_path": "Main/ProcessScan"},
        {"event": "transition", "path": "Main/ProcessScan", "node_id": "ProcessScan", "status": "SUCCESS"},
        {"event": "finished", "root_status": "SUCCESS", "exit_code": 0, "tick_count": 9},
    ]


def test_the_view_shows_each_node_with_its_latest_status_indented_by_depth() -> None:
    view = TreeView()
    for record in _records():
        view.apply(record)
    lines = _rendered(view)
    assert lines[0] == "tree SUCCESS  ticks 9"
    assert lines[1].split() == ["Sequence", "RUNNING"]
    assert lines[2].startswith("▶   ProcessScan") and lines[2].split()[-1] == "SUCCESS"


def test_off_a_terminal_progress_lines_are_printed_when_the_root_status_changes() -> None:
    stream = io.StringIO()
    console = Console(stream, live=False, colour=False, progress_interval_s=3600)
    console.register("coral")
    view = TreeView()
    for record in _records():
        view.apply(record)
        console.show(view)
    lines = stream.getvalue().splitlines()
    assert lines == [
        "coral | tree IDLE ticks=0",
        "coral | tree RUNNING ticks=7 active=Main/ProcessScan",
        "coral | tree SUCCESS ticks=9 active=Main/ProcessScan",
    ]
    assert "\x1b[" not in stream.getvalue()


def test_component_lines_are_prefixed_with_the_component_name() -> None:
    stream = io.StringIO()
    console = Console(stream, live=False, colour=False)
    for name in ("slam", "bag_player"):
        console.register(name)
    console.log("slam", "Component slam ready\n")
    assert stream.getvalue() == "slam       | Component slam ready\n"


def test_the_status_tail_reads_only_complete_new_lines(tmp_path: Path) -> None:
    path = tmp_path / "status.jsonl"
    tail = StatusTail(path)
    assert tail.read() == []
    path.write_text(json.dumps({"event": "a"}) + "\n" + '{"event": "b"')
    assert tail.read() == [{"event": "a"}]
    with path.open("a") as handle:
        handle.write("}\n")
    assert tail.read() == [{"event": "b"}]


def test_the_outline_of_the_example_gives_each_node_uid_its_depth() -> None:
    tree = Path(__file__).resolve().parents[3] / "examples" / "lidar-slam" / "tree.xml"
    outline = outline_of(tree)
    assert (outline[1].depth, outline[1].node_id) == (0, "Sequence")
    assert (outline[2].depth, outline[2].label) == (1, "SubTree StartSLAM")
    assert (outline[4].depth, outline[4].node_id) == (3, "EnableLocalization")
    assert (outline[15].depth, outline[15].label) == (4, "SubTree IterateSLAM")
    assert (outline[17].depth, outline[17].node_id) == (6, "ProcessScan")
    view = TreeView(outline=outline)
    view.apply(
        {
            "event": "transition",
            "path": "IterateSLAM::15/ProcessScan::17",
            "node_id": "ProcessScan",
            "status": "RUNNING",
        }
    )
    view.apply({"event": "transition", "path": "IterateSLAM::15", "node_id": "SubTree", "status": "RUNNING"})
    subtree, scan = _rendered(view)[1:]
    # Indented by the outline's depth (two spaces a level after the marker), statuses in one column.
    assert subtree.index("SubTree IterateSLAM") == 2 + 2 * 4 and scan.index("ProcessScan") == 2 + 2 * 6
    assert subtree.endswith("RUNNING") and scan.endswith("RUNNING") and len(subtree) == len(scan)
