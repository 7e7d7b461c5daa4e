"""`coral run --tree-png`: the tree drawn as a picture, each node in the colour of its last status."""

from __future__ import annotations

from pathlib import Path

import pytest
from coral import tree_picture
from coral.local.console import TreeView, outline_of
from fixtures.pictures import count_near, pixels

EXAMPLE_TREE = Path(__file__).resolve().parents[3] / "examples" / "lidar-slam" / "tree.xml"


def _hex(colour: str) -> tuple[int, int, int]:
    return int(colour[1:3], 16), int(colour[3:5], 16), int(colour[5:7], 16)


def test_each_node_is_drawn_in_the_colour_of_its_last_status(tmp_path: Path) -> None:
    view = TreeView(outline=outline_of(EXAMPLE_TREE))
    for path, node_id, status in [
        ("Sequence::1", "Sequence", "RUNNING"),
        ("Sequence::1/StartSLAM::2", "SubTree", "SUCCESS"),
        ("Sequence::1/StartSLAM::2/Sequence::3/EnableLocalization::4", "EnableLocalization", "SUCCESS"),
        ("Sequence::1/StartSLAM::2/Sequence::3/EnableLocalization::4", "EnableLocalization", "IDLE"),
        ("Sequence::1/Retry::9/Fallback::10/IsStopRequested::11", "IsStopRequested", "FAILURE"),
    ]:
        view.apply({"event": "transition", "path": path, "node_id": node_id, "status": status})
    # A node back to IDLE keeps the colour of what it last returned.
    assert view.last_statuses() == {1: "RUNNING", 2: "SUCCESS", 4: "SUCCESS", 11: "FAILURE"}

    target = tree_picture.draw_tree(view.outline, view.last_statuses(), tmp_path / "tree.png", "lidar-slam")
    rgb = pixels(target, tree_picture.size_px(view.outline), min_ink=0.01)
    green, red, yellow = (_hex(tree_picture.FILL[s]) for s in ("SUCCESS", "FAILURE", "RUNNING"))
    # Two green boxes, one red, one yellow (each box holds a few hundred pixels of its fill).
    assert count_near(rgb, green, 6) > 2 * count_near(rgb, red, 6) > 0
    assert count_near(rgb, yellow, 6) > 200


def test_a_wider_tree_gives_a_wider_picture() -> None:
    outline = outline_of(EXAMPLE_TREE)
    narrow = {uid: node for uid, node in outline.items() if uid <= 8}
    assert tree_picture.size_px(outline)[0] > tree_picture.size_px(narrow)[0]


def test_an_unreadable_tree_is_refused_with_the_target_named(tmp_path: Path) -> None:
    (tmp_path / "broken.xml").write_text("<root><BehaviorTree")
    with pytest.raises(ValueError, match="tree.png"):
        tree_picture.draw_tree(outline_of(tmp_path / "broken.xml"), {}, tmp_path / "tree.png", "t")
