"""A behavior tree as a PNG: one box a node, coloured by the last status it reported.

Drawn with matplotlib (Agg) from the tree file's outline (`coral.local.console.outline_of`, nodes
numbered depth-first as the engine's uids) and a uid -> status map. `coral run --tree-png` feeds it
every node's last status from the executor's records; `coral demo --tree-png` what the
CoralInstance reports (the root, the active node, the last failure). Nodes with no status are
drawn white ("not reported").
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

from coral import figures

# Groot2's palette, lightened so black labels stay readable.
FILL = {
    "SUCCESS": "#8ed08e",
    "FAILURE": "#f08a8a",
    "RUNNING": "#f5d76e",
    "IDLE": "#d9d9d9",
    "SKIPPED": "#bdbdbd",
}
NOT_REPORTED = "#ffffff"
# Layout units: one leaf slot is this many inches wide, one level this many inches tall.
SLOT_IN, LEVEL_IN = 1.6, 0.9
MAX_WIDTH_IN = 60.0


class Node(Protocol):
    depth: int
    label: str


@dataclass
class _Placed:
    uid: int
    label: str
    depth: int
    children: list[_Placed] = field(default_factory=list)
    x: float = 0.0


def _hierarchy(outline: Mapping[int, Node]) -> list[_Placed]:
    """The roots of the outline (depth-first order with depths) as a tree of placed nodes."""
    roots: list[_Placed] = []
    stack: list[_Placed] = []
    for uid in sorted(outline):
        node = _Placed(uid, outline[uid].label, outline[uid].depth)
        while stack and stack[-1].depth >= node.depth:
            stack.pop()
        (stack[-1].children if stack else roots).append(node)
        stack.append(node)
    return roots


def _place(node: _Placed, next_slot: list[float]) -> None:
    """Leaves take consecutive slots; a parent sits centred over its children."""
    if not node.children:
        node.x = next_slot[0]
        next_slot[0] += 1.0
        return
    for child in node.children:
        _place(child, next_slot)
    node.x = (node.children[0].x + node.children[-1].x) / 2


def _walk(nodes: list[_Placed]) -> list[_Placed]:
    out: list[_Placed] = []
    for node in nodes:
        out.append(node)
        out.extend(_walk(node.children))
    return out


def _layout(outline: Mapping[int, Node]) -> tuple[list[_Placed], float, int, tuple[float, float]]:
    """(every node placed, slots used, deepest depth, figure size in inches)."""
    roots = _hierarchy(outline)
    slots = [0.0]
    for root in roots:
        _place(root, slots)
    nodes = _walk(roots)
    depth = max(node.depth for node in nodes)
    size = (min(MAX_WIDTH_IN, max(6.0, slots[0] * SLOT_IN)), max(3.0, (depth + 1) * LEVEL_IN + 1.2))
    return nodes, slots[0], depth, size


def size_px(outline: Mapping[int, Node]) -> tuple[int, int]:
    """(width, height) of the picture `draw_tree` makes of `outline`."""
    width, height = _layout(outline)[3]
    return round(width * figures.DPI), round(height * figures.DPI)


def draw_tree(outline: Mapping[int, Node], statuses: Mapping[int, str], target: Path, title: str) -> Path:
    """Writes the picture (`size_px(outline)` pixels) to `target` (aside, then renamed); returns it.

    Raises:
        ValueError: the outline is empty (the tree file could not be read).
    """
    if not outline:
        raise ValueError(f"no tree to draw into {target} (the tree file could not be read)")
    from matplotlib.patches import Patch

    nodes, slots, depth, (width, height) = _layout(outline)
    figure = figures.new_figure(width, height)
    axes = figure.add_subplot()
    axes.set_xlim(-0.6, slots - 0.4)
    axes.set_ylim(-depth - 0.6, 0.6)
    axes.axis("off")
    font = 8 if width < MAX_WIDTH_IN else 6
    for node in nodes:
        for child in node.children:
            axes.plot(
                [node.x, child.x], [-node.depth, -child.depth], color="#555555", linewidth=0.8, zorder=1
            )
    for node in nodes:
        status = statuses.get(node.uid)
        axes.text(
            node.x,
            -node.depth,
            node.label.replace(" ", "\n", 1) if len(node.label) > 14 else node.label,
            ha="center",
            va="center",
            fontsize=font,
            zorder=2,
            bbox={
                "boxstyle": "round,pad=0.3",
                "facecolor": FILL.get(status or "", NOT_REPORTED),
                "edgecolor": "#333333",
                "linewidth": 0.8,
            },
        )
    legend = [Patch(facecolor=colour, edgecolor="#333333", label=name) for name, colour in FILL.items()]
    legend.append(Patch(facecolor=NOT_REPORTED, edgecolor="#333333", label="not reported"))
    axes.legend(handles=legend, loc="lower left", fontsize=7, ncol=len(legend), frameon=False)
    axes.set_title(title, fontsize=10)
    return figures.save_png(figure, target)
