"""Seeded generator of random BT.CPP XML trees over the built-in controls, decorators, scripted leaves,
ports (Script, SetBlackboard, Switch, Precondition, SubTree remaps) and pre/post-condition attributes.

Every node gets a unique name, leaves get outcome scripts (with RUNNING). Wall-clock nodes (Sleep,
Delay, Timeout) and nodes newer than the oracle's BT.CPP (TryCatch) are left out.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field
from xml.sax.saxutils import quoteattr

CONTROLS = [
    "Sequence",
    "Fallback",
    "AsyncSequence",
    "AsyncFallback",
    "SequenceWithMemory",
    "ReactiveSequence",
    "ReactiveFallback",
    "Parallel",
    "ParallelAll",
    "IfThenElse",
    "WhileDoElse",
    "Switch2",
    "Switch3",
    "Switch4",
    "Switch5",
    "Switch6",
]
DECORATORS = [
    "Inverter",
    "ForceSuccess",
    "ForceFailure",
    "KeepRunningUntilFailure",
    "Repeat",
    "RetryUntilSuccessful",
    "RunOnce",
    "Precondition",
    "SkipUnlessUpdated",
    "WaitValueUpdate",
    "SubTree",
    "LoopInt",
    "LoopString",
    "LoopDouble",
    "LoopBool",
]
VARS = {"v": 0, "w": 0, "h": 0, "sw": 1}  # host-set int entries; `sws` is the Switch's string entry
SCRIPTS = [
    "v := v + 1",
    "w := w + 1",
    "sw := (sw + 1) > 3 ? 1 : sw + 1",
    "v := 0",
    "h := h + 2; w := w + v",
    "sws := 'b'",
    "sws := '2'",
]
CONDITIONS = ["v > 2", "w < 3", "v == w", "sw != 2", "v >= 1 && w <= 4", "h > 1 || v < 1"]
PRE = ["_skipIf", "_successIf", "_failureIf", "_while"]
POST = ["_onSuccess", "_onFailure", "_post", "_onHalted"]


@dataclass
class Generated:
    xml: str
    outcomes: dict[str, list[int]]
    mode: str
    node_count: int
    used: set[str] = field(default_factory=set)


class _Gen:
    def __init__(self, seed: int, forever: bool) -> None:
        self.rng = random.Random(seed)
        self.forever = forever
        self.count = 0
        self.outcomes: dict[str, list[int]] = {}
        self.subtrees: list[str] = []
        self.used: set[str] = set()

    def name(self, prefix: str) -> str:
        self.count += 1
        return f"{prefix}{self.count}"

    def attrs(self, pairs: dict[str, str]) -> str:
        return "".join(f" {k}={quoteattr(v)}" for k, v in pairs.items())

    def conditions(self, attrs: dict[str, str]) -> None:
        rng = self.rng
        if rng.random() < 0.12:
            attrs[rng.choice(PRE)] = rng.choice(CONDITIONS)
        if rng.random() < 0.12:
            attrs[rng.choice(POST)] = rng.choice(SCRIPTS)

    def leaf(self) -> str:
        rng = self.rng
        kind = rng.choices(
            [
                "Leaf",
                "Cond",
                "Script",
                "ScriptCondition",
                "AlwaysSuccess",
                "AlwaysFailure",
                "SetBlackboard",
                "WasEntryUpdated",
                "UnsetBlackboard",
            ],
            [30, 15, 6, 6, 3, 3, 3, 2, 1],
        )[0]
        self.used.add(kind)
        name = self.name("n")
        attrs = {"name": name}
        if kind == "Leaf":
            self.outcomes[name] = [rng.choice([1, 1, 2, 2, 3]) for _ in range(rng.randint(1, 5))]
        elif kind == "Cond":
            self.outcomes[name] = [rng.choice([2, 3]) for _ in range(rng.randint(1, 4))]
        elif kind == "Script":
            attrs["code"] = rng.choice(SCRIPTS)
        elif kind == "ScriptCondition":
            attrs["code"] = rng.choice(CONDITIONS)
        elif kind == "SetBlackboard":
            attrs["output_key"] = rng.choice(["v", "w"])
            attrs["value"] = rng.choice(["1", "3", "{w}", "{v}"])
        elif kind == "UnsetBlackboard":
            attrs["key"] = "sws"
        elif kind == "WasEntryUpdated":
            attrs["entry"] = rng.choice(["{v}", "{w}"])
        self.conditions(attrs)
        return f"<{kind}{self.attrs(attrs)}/>"

    def node(self, depth: int) -> str:
        rng = self.rng
        if depth <= 0 or rng.random() < 0.3:
            return self.leaf()
        if rng.random() < 0.55:
            return self.control(depth)
        return self.decorator(depth)

    def control(self, depth: int) -> str:
        rng = self.rng
        kind = rng.choice(CONTROLS)
        self.used.add(kind)
        attrs = {"name": self.name("c")}
        if kind in ("IfThenElse", "WhileDoElse"):
            n = rng.choice([2, 3])
        elif kind.startswith("Switch"):
            cases = int(kind[-1])
            n = cases + 1
            attrs["variable"] = "{sws}"
            for i in range(1, cases + 1):
                attrs[f"case_{i}"] = rng.choice(["1", "2", "b", "3"])
        else:
            n = rng.randint(1, 4)
        if kind == "Parallel":
            attrs["success_count"] = str(rng.choice([-1, -2, 1, 2]) if n >= 2 else rng.choice([-1, 1]))
            attrs["failure_count"] = str(rng.choice([1, -1] + ([2] if n >= 2 else [])))
        elif kind == "ParallelAll":
            attrs["max_failures"] = str(rng.choice([1, -1] + ([2] if n >= 2 else [])))
        self.conditions(attrs)
        children = "".join(self.node(depth - 1) for _ in range(n))
        return f"<{kind}{self.attrs(attrs)}>{children}</{kind}>"

    def decorator(self, depth: int) -> str:
        rng = self.rng
        kind = rng.choice(DECORATORS)
        self.used.add(kind)
        attrs = {"name": self.name("d")}
        if kind == "Repeat":
            # -1 loops forever under tick_once when the child completes synchronously (in BT.CPP too).
            attrs["num_cycles"] = str(rng.choice([1, 2, 3, -1] if self.forever else [1, 2, 3]))
        elif kind == "RetryUntilSuccessful":
            attrs["num_attempts"] = str(rng.choice([1, 2, 3, -1] if self.forever else [1, 2, 3]))
        elif kind == "RunOnce":
            attrs["then_skip"] = rng.choice(["true", "false"])
        elif kind == "Precondition":
            attrs["if"] = rng.choice(CONDITIONS)
            attrs["else"] = rng.choice(["FAILURE", "SUCCESS", "RUNNING"])
        elif kind in ("SkipUnlessUpdated", "WaitValueUpdate"):
            attrs["entry"] = rng.choice(["{v}", "{w}"])
        elif kind == "LoopInt":
            attrs["queue"] = rng.choice(["1;2;3", "4", "2;2"])
            attrs["value"] = "{lv}"
            attrs["if_empty"] = rng.choice(["SUCCESS", "FAILURE", "SKIPPED"])
        elif kind == "LoopDouble":
            attrs["queue"] = rng.choice(["1.5;2", "0.25"])
            attrs["value"] = "{ld}"
        elif kind == "LoopBool":
            attrs["queue"] = rng.choice(["true;false", "0;1;1"])
            attrs["value"] = "{lb}"
        elif kind == "LoopString":
            attrs["queue"] = rng.choice(["b;2", "1;b;3", "2"])
            attrs["value"] = "{sws}"
        elif kind == "SubTree":
            return self.subtree(depth, attrs)
        self.conditions(attrs)
        return f"<{kind}{self.attrs(attrs)}>{self.node(depth - 1)}</{kind}>"

    def subtree(self, depth: int, attrs: dict[str, str]) -> str:
        rng = self.rng
        slot = len(self.subtrees)
        tree_id = f"Sub{slot + 1}"
        self.subtrees.append("")
        body = self.node(depth - 1)
        self.subtrees[slot] = f'<BehaviorTree ID="{tree_id}">{body}</BehaviorTree>'
        attrs["ID"] = tree_id
        if rng.random() < 0.5:
            attrs["_autoremap"] = "true"
        else:
            for key in VARS:
                attrs[key] = rng.choice(["{" + key + "}", "{=}"])
        return f"<SubTree{self.attrs(attrs)}/>"


def generate(seed: int, depth: int = 4) -> Generated:
    mode = "exactly_once" if seed % 3 else "once"
    gen = _Gen(seed, forever=mode == "exactly_once")
    body = gen.node(depth)
    trees = "".join([f'<BehaviorTree ID="MainTree">{body}</BehaviorTree>'] + gen.subtrees)
    xml = f'<root BTCPP_format="4" main_tree_to_execute="MainTree">{trees}</root>'
    return Generated(xml, gen.outcomes, mode, gen.count, gen.used)
