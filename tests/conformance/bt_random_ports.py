"""Seeded generator of small trees whose typed ports read blackboard entries, for the port
differential test against BT.CPP.

Each tree writes an entry (a script, SetBlackboard's text, a host entry or a SubTree literal) with
a value of any kind (ints, doubles, infinities, NaN, numeric and non-numeric text, queues), then
reads it through the typed ports of the built-in nodes: Repeat, RetryUntilSuccessful, Parallel,
ParallelAll, RunOnce, the Loops' queues, and SetBlackboard copying it into
typed host entries. It reaches what `bt_random_trees` leaves to literals: how a port converts an
entry that holds another kind, and how SetBlackboard parses text into a typed entry.

What the oracle (BT.CPP 4.8) does differently from 4.10 on purpose is left out (docs/bt-engine.md):
a Loop never reads a text entry that no queue port declared (a host or SubTree text), SubTree
literals are never numbers, a Loop never meets an entry a SetBlackboard declared, and scripts
write no `true`/`false`. Precondition's `else` is left out:
an int outside NodeStatus there crashes BT.CPP (the engine refuses it). Switch is left to the random
trees: 4.8 matches the numeric prefix of the text kinds drawn here. There are no host ints, and no
SetBlackboard copies into an entry a port declared int: a script's integer is an int64 in BT.CPP,
another C++ type than that int, which makes the copy throw there.
"""

from __future__ import annotations

import random
from xml.sax.saxutils import quoteattr

HOST: dict[str, object] = {"hd": 2.0, "hs": "2", "hb": True, "hl": "1;2"}
SCRIPT_VALUES = [
    "2",
    "0",
    "-1",
    "3.0",
    "2.5",
    "-0.0",
    "1e0",
    "0x2",
    "(1/0)",
    "(0/0)",
    "'3'",
    "'3abc'",
    "' 2'",
    "'x'",
    "''",
    "'true'",
    "'1'",
    "'0'",
    "'-1'",
    "'+2'",
    "'0x2'",
    "'2;3'",
    "'1;2;x'",
    "'true;false'",
    "'1.5;2'",
]
TEXTS = ["2", "0", "-1", "3.0", "2.5", "3abc", " 2", "x", "", "true", "false", "1;2", "2;3", "1.5;2", "+2"]
SUBTREE_TEXTS = [" 2", "3abc", "x", "true", "false", "1;2;x", "0x2", "+2", "1.5;2", "2;3"]
ENTRY_KEYS = ["{x}", "{x}", "{x}", "{hd}", "{hs}", "{hb}", "{hl}"]


def _reader(rng: random.Random, key: str, flavor: str) -> str:
    typed = [
        f'<Repeat num_cycles="{key}"><AlwaysSuccess/></Repeat>',
        f'<RetryUntilSuccessful num_attempts="{key}"><AlwaysFailure/></RetryUntilSuccessful>',
        f'<Parallel success_count="{key}" failure_count="1"><AlwaysSuccess/><AlwaysSuccess/></Parallel>',
        f'<Parallel success_count="-1" failure_count="{key}"><AlwaysFailure/><AlwaysSuccess/></Parallel>',
        f'<ParallelAll max_failures="{key}"><AlwaysFailure/><AlwaysSuccess/></ParallelAll>',
        f'<RunOnce then_skip="{key}"><AlwaysSuccess/></RunOnce>',
    ]
    copies = [
        f'<SetBlackboard value="{key}" output_key="o"/>',
        f'<SetBlackboard value="{key}" output_key="hd"/>',
        f'<SetBlackboard value="{key}" output_key="hb"/>',
    ]
    loops = [
        f'<LoopInt queue="{key}" value="{{o}}"><AlwaysSuccess/></LoopInt>',
        f'<LoopDouble queue="{key}" value="{{o}}"><AlwaysSuccess/></LoopDouble>',
        f'<LoopString queue="{key}" value="{{o}}"><AlwaysSuccess/></LoopString>',
        f'<LoopBool queue="{key}" value="{{o}}"><AlwaysSuccess/></LoopBool>',
    ]
    if flavor == "copies":
        return rng.choice(copies)
    if flavor == "subtree":
        return rng.choice(typed + copies)
    return rng.choice(typed + (loops if key == "{x}" else []))


def _writer(rng: random.Random) -> str:
    roll = rng.random()
    if roll < 0.55:
        return f"<Script code={quoteattr('x := ' + rng.choice(SCRIPT_VALUES))}/>"
    if roll < 0.85:
        return f'<SetBlackboard value={quoteattr(rng.choice(TEXTS))} output_key="x"/>'
    return f'<SetBlackboard value={quoteattr(rng.choice(TEXTS))} output_key="{rng.choice(["hd", "hb"])}"/>'


def generate(seed: int) -> str:
    rng = random.Random(seed)
    if rng.random() < 0.25:
        literal = quoteattr(rng.choice(SUBTREE_TEXTS))
        readers = "".join(_reader(rng, "{x}", "subtree") for _ in range(2))
        return (
            '<root BTCPP_format="4" main_tree_to_execute="M"><BehaviorTree ID="M">'
            f'<SubTree ID="S" _autoremap="true" x={literal}/></BehaviorTree>'
            f'<BehaviorTree ID="S"><Sequence>{readers}</Sequence></BehaviorTree></root>'
        )
    # A tree either reads x through typed ports (Loops included) or copies it with SetBlackboard.
    # A SetBlackboard reading x declares it untyped before a Loop's port can declare it a queue
    # (and a Loop reading such a text is a 4.10 addition); and a copy of x made after a typed port
    # declared it (int, bool) is declared so too, which a script's int64 then does not match.
    flavor = rng.choice(["typed", "copies"])
    nodes = []
    for _ in range(rng.randint(1, 3)):
        nodes.append(_writer(rng))
        nodes.append(_reader(rng, rng.choice(ENTRY_KEYS), flavor))
    body = "".join(nodes)
    return (
        f'<root BTCPP_format="4" main_tree_to_execute="M"><BehaviorTree ID="M"><Sequence>{body}'
        "</Sequence></BehaviorTree></root>"
    )
