"""Seeded generator of random BT.CPP XML trees for the differential test against real BT.CPP.

It covers the built-in controls and decorators, scripted leaves, and what missions do with the
blackboard: host entries of several types, scripts with every operator on mixed types (written
with parentheses so BT.CPP 4.8's grammar and 4.10's parse them alike), all pre/post-condition
attributes, SetBlackboard/UnsetBlackboard, WasEntryUpdated/SkipUnlessUpdated/WaitValueUpdate,
Switch and Loop* on blackboard values, and nested SubTrees remapped with `{key}`, `{=}`,
`_autoremap`, literals, `_private` and `@root` keys. A share of the trees is broken on purpose.

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
# Host-set entries: ints, a double and a string (the string entry is untyped, as in BT.CPP).
VARS: dict[str, object] = {"v": 0, "w": 0, "h": 0, "sw": 1, "f": 0.5, "s": "a"}
SCRIPTS = [
    "v := v + 1",
    "w := w + 1",
    "sw := (sw + 1) > 3 ? 1 : sw + 1",
    "v := 0",
    "h := h + 2; w := w + v",
    "sws := 'b'",
    "sws := '2'",
    "sws := 2",
    "f := f * 2",
    "f /= 2",
    "v -= 1",
    "w *= 2",
    "h += 1",
    "s := s .. 'x'",
    "s := s + 'y'",
    "s += 'z'",
    "t := 'n' .. v",
    "t := 'n' .. (f / 2)",
    "u := v / 0",
    "u := (v & 3) | 4",
    "u := w ^ 5",
    "u := ~h",
    "u := -v",
    "u := !v",
    "v = '7'",
    "v = 'q'",
    "s := 3",
    "f := 2",
    "w := 2.5",
    "v = 4.0",
    "q := v > 1 ? 'big' : 'small'",
    "@g := v",
    "@g := @g + 1",
    "_p := 1",
    "_p := _p + 1",
    "lv := 3",
    "ld := 'x'",
    "k := k + 1",
    "nk := s",
    "entry := v",
    "t := v .. w",
    "lq := '1;2;3'",
    "lq := '4'",
    "lsq := 'b;2;a'",
]
CONDITIONS = [
    "v > 2",
    "w < 3",
    "v == w",
    "sw != 2",
    "v >= 1 && w <= 4",
    "h > 1 || v < 1",
    "1 < v <= 3",
    "5 < 1 <= zz",
    "s == 'a'",
    "sws == 'b'",
    "f >= 0.5",
    "(v & 1) == 1",
    "!(v == 1)",
    "q != 'big'",
    "@g > 1",
    "t == 'n1'",
    "sws == 2",
]
PRE = ["_skipIf", "_successIf", "_failureIf", "_while"]
POST = ["_onSuccess", "_onFailure", "_post", "_onHalted"]
KEYS = ["v", "w", "h", "s", "f", "sws", "lv", "q", "_p", "lq"]
BROKEN = [
    "unused tree with a childless decorator",
    "unknown node",
    "script syntax",
    "port type clash",
    "undefined subtree",
    "bad literal",
]


@dataclass
class Generated:
    xml: str
    outcomes: dict[str, list[int]]
    mode: str
    node_count: int
    used: set[str] = field(default_factory=set)
    broken: str = ""


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
            post = rng.choice(POST)
            # BT.CPP's Tree destructor runs haltTree() too, and an _onHalted script that throws
            # there terminates the process: _onHalted only records which node was halted last.
            attrs[post] = f"ho := '{attrs['name']}'" if post == "_onHalted" else rng.choice(SCRIPTS)

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
            [30, 15, 9, 6, 3, 3, 4, 2, 2],
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
            attrs["output_key"] = key = rng.choice(["v", "w", "s", "sws", "f", "nk", "@g"])
            values = ["1", "3", "x", "2.5", "{w}", "{v}", "{s}", "{f}", "{src}"]
            if key == "sws":
                # Switch reads "2.5" as the int 2 in BT.CPP 4.8 but not in 4.10: not generated.
                values.remove("2.5")
            attrs["value"] = rng.choice(values)
        elif kind == "UnsetBlackboard":
            attrs["key"] = rng.choice(["sws", "v", "s", "_p", "nk", "lv"])
        elif kind == "WasEntryUpdated":
            attrs["entry"] = rng.choice(["{v}", "{w}", "{s}", "{sws}", "{f}", "{=}"])
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
            attrs["variable"] = variable = rng.choice(["{sws}", "{sws}", "{s}", "{t}"])
            # Scripts append to s ("3" .. "x"): a numeric case would match "3x" by its prefix in
            # 4.8 and not in 4.10, so s meets text cases only.
            values = ["b", "a", "n1"] if variable == "{s}" else ["1", "2", "b", "3", "a", "n1"]
            for i in range(1, cases + 1):
                attrs[f"case_{i}"] = rng.choice(values)
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
        # SubTrees get a larger share: their scoping rules are where engines drift apart.
        kind = "SubTree" if rng.random() < 0.3 else rng.choice(DECORATORS)
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
            attrs["entry"] = rng.choice(["{v}", "{w}", "{s}", "{sws}", "{k}", "{@g}", "{=}"])
        elif kind == "LoopInt":
            # {lq} is a shared queue that scripts fill and the loop consumes in place.
            attrs["queue"] = rng.choice(["1;2;3", "4", "2;2", "{lq}"])
            attrs["value"] = rng.choice(["{lv}", "{v}", "{k}"])
            attrs["if_empty"] = rng.choice(["SUCCESS", "FAILURE", "SKIPPED"])
        elif kind == "LoopDouble":
            attrs["queue"] = rng.choice(["1.5;2", "0.25", "3.0"])
            attrs["value"] = rng.choice(["{ld}", "{f}", "{k}"])
        elif kind == "LoopBool":
            attrs["queue"] = rng.choice(["true;false", "0;1;1"])
            attrs["value"] = "{lb}"
        elif kind == "LoopString":
            attrs["queue"] = rng.choice(["b;2", "1;b;3", "2", "{lsq}"])
            attrs["value"] = rng.choice(["{sws}", "{s}"])
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
        if rng.random() < 0.4:
            attrs["_autoremap"] = "true"
        for key in KEYS:
            choice = rng.random()
            if choice < 0.35:
                attrs[key] = "{" + key + "}"
            elif choice < 0.5:
                attrs[key] = "{=}"
            elif choice < 0.6:
                # The queue never moves to another entry: a text entry is a queue in 4.10, not in 4.8.
                attrs[key] = "{" + (key if key == "lq" else rng.choice(KEYS)) + "}"
            elif choice < 0.68 and key != "lq":
                # Non-numeric: BT.CPP 4.10 stores numeric SubTree literals as numbers, 4.8 as text.
                # No text for a queue: 4.10 reads a text entry as a queue, 4.8 refuses it.
                attrs[key] = rng.choice(["lit", "b", "n1"])
        return f"<SubTree{self.attrs(attrs)}/>"

    def break_tree(self, body: str, trees: list[str]) -> tuple[str, str]:
        """Makes the tree invalid in one of BROKEN's ways; BT.CPP and the engine must both refuse it."""
        rng = self.rng
        how = rng.choice(BROKEN)
        if how == "unused tree with a childless decorator":
            trees.append('<BehaviorTree ID="Unused"><Inverter/></BehaviorTree>')
        elif how == "unknown node":
            trees.append('<BehaviorTree ID="Unused"><Sequence><NoSuchNode/></Sequence></BehaviorTree>')
        elif how == "script syntax":
            body = f'<Sequence>{body}<Script code="v := (1"/></Sequence>'
        elif how == "port type clash":
            clash = '<Precondition if="1" else="{v}"><AlwaysSuccess/></Precondition>'
            body = f"<Sequence>{body}{clash}</Sequence>"
        elif how == "undefined subtree":
            body = f'<Sequence>{body}<SubTree ID="Nowhere"/></Sequence>'
        else:
            body = f'<Sequence>{body}<Repeat num_cycles="many"><AlwaysSuccess/></Repeat></Sequence>'
        return body, how


def generate(seed: int, depth: int = 4, broken_share: float = 0.0) -> Generated:
    mode = "exactly_once" if seed % 3 else "once"
    gen = _Gen(seed, forever=mode == "exactly_once")
    body = gen.node(depth)
    extra: list[str] = []
    how = ""
    if broken_share and gen.rng.random() < broken_share:
        body, how = gen.break_tree(body, extra)
    trees = "".join([f'<BehaviorTree ID="MainTree">{body}</BehaviorTree>'] + gen.subtrees + extra)
    xml = f'<root BTCPP_format="4" main_tree_to_execute="MainTree">{trees}</root>'
    return Generated(xml, gen.outcomes, mode, gen.count, gen.used, how)
