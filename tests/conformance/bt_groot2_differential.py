"""Runs the same trees in real BT.CPP's Groot2Publisher (behaviortreepy) and in coral_core.bt's, and
reads both through one pyzmq client (`coral_core.bt.groot2.client`): the FULLTREE parsed as a tree,
STATUS after every tick, every subtree's blackboard after every tick (MessagePack decoded), and the
recorded transitions (uid and status in order; times ignored). `bt_groot2_hooks` adds hooks.

Used by test_bt_groot2_differential.py;
`PYTHONPATH=tests python tests/conformance/bt_groot2_differential.py N`
runs N random trees (`make bench-bt` runs 2,000).
"""

from __future__ import annotations

import math
import sys
import time
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from bt_groot2_engines import BTCPP, CORAL, EngineHost, LoadRequest
from bt_random_trees import VARS, generate
from coral_core.bt.builder import literal_value
from coral_core.bt.groot2.client import Groot2Client

TICKS = 15
ROOT = "ROOT"


@dataclass
class Trace:
    verdict: str
    fulltree: Any = None
    models: Any = None
    statuses: list[Any] = field(default_factory=list)  # root status per tick ("ERROR" on a tick error)
    status_maps: list[dict[int, int]] = field(default_factory=list)  # before the first tick, then each
    transitions: list[list[tuple[int, int]]] = field(default_factory=list)
    boards: list[Any] = field(default_factory=list)
    extra_root: list[bool] = field(default_factory=list)  # 4.10's "ROOT" export, ours only

    def compared(self) -> tuple[Any, ...]:
        return (self.verdict, self.fulltree, self.statuses, self.status_maps, self.transitions, self.boards)


FIELDS = ("verdict", "fulltree", "statuses", "status_maps", "transitions", "boards")


def node_shape(element: ET.Element) -> tuple[Any, ...]:
    return (element.tag, tuple(sorted(element.attrib.items())), tuple(node_shape(c) for c in element))


def fulltree_shape(xml_text: str) -> tuple[Any, Any]:
    """The BehaviorTree elements as nested (tag, attributes, children), and the node models as
    (element, ID, ports as (direction, name, default)) keyed by ID."""
    root = ET.fromstring(xml_text)
    trees = tuple(node_shape(t) for t in root.findall("BehaviorTree"))
    models = {}
    for model in root.find("TreeNodesModel") or ():
        ports = tuple(sorted((p.tag, p.get("name"), p.get("default")) for p in model))
        models[model.get("ID")] = (model.tag, ports)
    return trees, models


def board_names(shape: Any) -> list[str]:
    names = []
    for tag, attrs, _children in shape:
        assert tag == "BehaviorTree"
        values = dict(attrs)
        names.append(values["_fullpath"] or values["ID"])
    return names


def comparable(value: Any) -> Any:
    """NaN as text with its sign ("-nan" as BT.CPP prints 0/0), so that equal dumps compare equal."""
    if isinstance(value, float) and math.isnan(value):
        return "-nan" if math.copysign(1.0, value) < 0 else "nan"
    if isinstance(value, dict):
        return {k: comparable(v) for k, v in value.items()}
    if isinstance(value, list):
        return [comparable(v) for v in value]
    return value


def observe(host: EngineHost, request: LoadRequest, ticks: int = TICKS) -> Trace:
    verdict, value = host.load(request)
    if verdict != "LOADED":
        return Trace(verdict)
    trace = Trace(verdict)
    try:
        with Groot2Client(port=value, timeout_s=10) as client:
            trace.fulltree, trace.models = fulltree_shape(client.fulltree())
            names = board_names(trace.fulltree)
            client.start_recording()
            trace.status_maps.append(client.status())
            for _ in range(ticks):
                kind, result = host.tick()
                trace.statuses.append(result if kind == "status" else "ERROR")
                trace.status_maps.append(client.status())
                trace.transitions.append([(uid, status) for _t, uid, status in client.transitions()])
                boards = comparable(client.blackboards(names))
                if isinstance(boards, dict) and ROOT in boards and ROOT not in names:
                    trace.extra_root.append(boards.pop(ROOT) == boards.get(names[0]))
                trace.boards.append(boards)
                if kind != "status":
                    break
    finally:
        host.drop()
    return trace


def literal_ports(shape: Any) -> dict[str, dict[str, str]]:
    """SubTree path -> its ports given as literals (not `{key}`), from the FULLTREE."""
    out: dict[str, dict[str, str]] = {}

    def walk(node: Any) -> None:
        tag, attrs, children = node
        values = dict(attrs)
        if tag == "SubTree":
            out[values["_fullpath"]] = {
                k: v for k, v in values.items() if k[:1].isalpha() and k != "ID" and not v.startswith("{")
            }
        for child in children:
            walk(child)

    for tree in shape:
        walk(tree)
    return out


def as_410_literals(trace: Trace) -> None:
    """BT.CPP 4.10 stores a SubTree's numeric literal port as a number, 4.8.2 as text; coral follows
    4.10, so 4.8.2's text for an unchanged literal is read as 4.10 would store it."""
    literals = literal_ports(trace.fulltree)
    for boards in trace.boards:
        for path, ports in literals.items():
            board = boards.get(path) if isinstance(boards, dict) else None
            for key, text in ports.items():
                if board and board.get(key) == text:
                    board[key] = literal_value(text)


@dataclass
class Report:
    trees: int = 0
    agreeing: int = 0
    rejected: int = 0
    tick_errors: int = 0
    requests: int = 0
    mismatches: list[str] = field(default_factory=list)
    seconds: float = 0.0


def model_mismatch(theirs: Trace, ours: Trace) -> str:
    """Node models must agree for every type the tree uses (ours lists only those)."""
    for node_id, model in (ours.models or {}).items():
        if theirs.models.get(node_id) != model:
            return f"model {node_id}: BT.CPP {theirs.models.get(node_id)} vs coral {model}"
    return ""


def compare(requests: Iterable[tuple[str, LoadRequest]], report: Report, ticks: int = TICKS) -> Report:
    start = time.monotonic()
    theirs_host, ours_host = EngineHost(BTCPP, 21000), EngineHost(CORAL, 41000)
    try:
        for label, request in requests:
            theirs = observe(theirs_host, request, ticks)
            ours = observe(ours_host, request, ticks)
            if theirs.verdict == "LOADED":
                as_410_literals(theirs)
            report.trees += 1
            report.requests += 4 + 3 * len(theirs.statuses)
            differs = [
                n for n, a, b in zip(FIELDS, theirs.compared(), ours.compared(), strict=True) if a != b
            ]
            problem = model_mismatch(theirs, ours) if theirs.verdict == "LOADED" and not differs else ""
            if not all(ours.extra_root):
                problem = problem or "the ROOT export differs from the main tree's board"
            if differs or problem:
                first = differs[0] if differs else "models"
                detail = problem or describe(first, theirs, ours)
                report.mismatches.append(f"{label} differs in {first}: {detail}\n  {request.xml[:500]}")
            else:
                report.agreeing += 1
                report.rejected += theirs.verdict == "REJECT"
                report.tick_errors += "ERROR" in theirs.statuses
    finally:
        theirs_host.close()
        ours_host.close()
    report.seconds = time.monotonic() - start
    return report


def describe(name: str, theirs: Trace, ours: Trace) -> str:
    a, b = getattr(theirs, name), getattr(ours, name)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        for i, (x, y) in enumerate(zip(a, b, strict=False)):
            if x != y:
                return f"[{i}] BT.CPP {str(x)[:400]} vs coral {str(y)[:400]}"
        return f"lengths {len(a)} vs {len(b)}"
    return f"BT.CPP {str(a)[:300]} vs coral {str(b)[:300]}"


def random_requests(seeds: Iterable[int], broken_share: float = 0.08) -> Iterable[tuple[str, LoadRequest]]:
    for seed in seeds:
        gen = generate(seed, broken_share=broken_share)
        yield f"seed {seed} ({gen.mode})", LoadRequest(gen.xml, gen.outcomes, gen.mode, dict(VARS))


def main() -> None:
    count = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
    first = int(sys.argv[2]) if len(sys.argv) > 2 else 0
    report = compare(random_requests(range(first, first + count)), Report())
    for line in report.mismatches[:10]:
        print(line)
    print(
        f"{report.agreeing} of {report.trees} random trees read the same through Groot2 in BT.CPP and "
        f"coral ({report.rejected} refused by both, {report.tick_errors} ending in a tick error; "
        f"{report.requests} requests to each) in {report.seconds:.0f} s"
    )


if __name__ == "__main__":
    main()
