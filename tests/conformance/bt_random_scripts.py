"""Seeded generator of small trees made of scripts, for the script differential test against BT.CPP.

Each tree is a Sequence of Script, ScriptCondition and pre/post-condition attributes whose code is
a random expression over literals of every kind (ints, doubles, hex, text that is or starts like a
number, booleans) and host entries of every kind (int, double, text, bool, a negative int), with
every operator, the ternary and every assignment. It reaches what the random trees of
`bt_random_trees` do not: how each operator treats mixed kinds, how text reads as a number, and
which values a condition accepts as a bool.

Every operand is parenthesized, so BT.CPP 4.8's grammar and 4.10's parse the code alike (see the
deliberate differences in docs/bt-engine.md). `true` and `false` appear only as operands of an
operator other than `..`: 4.8 makes them integers and 4.10 doubles, which differ only once stored or
printed.
"""

from __future__ import annotations

import random
from xml.sax.saxutils import quoteattr

# Host entries: BT.CPP types them from the values (int64, double, string, bool).
VARS: dict[str, object] = {"v": 0, "w": 3, "f": 0.5, "s": "a", "n": "12", "b": True, "neg": -2}
LITERALS = ["0", "1", "2", "-1", "0.5", "2.5", "1e2", "0x1F", "3.0", "0.0"]
TEXTS = ["'a'", "''", "'12'", "'true'", "'x y'", "'12abc'", "' 7'", "'0'", "'-3'"]
BOOLEANS = ["true", "false"]
# Host entries, and names that exist only once a script created them with `:=`.
NAMES = ["v", "w", "f", "s", "n", "b", "neg", "@v"]
CREATED = ["u", "t", "@g"]
BINARY = ["+", "-", "*", "/", "..", "&", "|", "^", "&&", "||", "==", "!=", "<", ">", "<=", ">="]
UNARY = ["-", "!", "~"]
ASSIGN = [":=", "=", "+=", "-=", "*=", "/="]
PRE = ["_skipIf", "_successIf", "_failureIf", "_while"]


def _operand(rng: random.Random, booleans: bool) -> str:
    pools = [LITERALS, TEXTS, NAMES, CREATED, BOOLEANS if booleans else LITERALS]
    return rng.choice(rng.choices(pools, [6, 1, 6, 0.5, 1])[0])


def expression(rng: random.Random, depth: int, booleans: bool = False) -> str:
    roll = rng.random()
    if depth <= 0 or roll < 0.3:
        return _operand(rng, booleans)
    if roll < 0.45:
        return f"{rng.choice(UNARY)}({expression(rng, depth - 1, True)})"
    if roll < 0.55:
        cond = expression(rng, depth - 1, True)
        return f"({cond}) ? ({expression(rng, depth - 1)}) : ({expression(rng, depth - 1)})"
    op = rng.choice(BINARY)
    typed = op != ".."
    return f"({expression(rng, depth - 1, typed)}) {op} ({expression(rng, depth - 1, typed)})"


def script(rng: random.Random) -> str:
    parts = []
    for _ in range(rng.randint(1, 3)):
        if rng.random() < 0.6:
            parts.append(f"{rng.choice(NAMES + CREATED)} {rng.choice(ASSIGN)} ({expression(rng, 2)})")
        else:
            parts.append(expression(rng, 2))
    return "; ".join(parts)


def generate(seed: int) -> str:
    rng = random.Random(seed)
    nodes = []
    for i in range(rng.randint(1, 4)):
        roll = rng.random()
        if roll < 0.5:
            nodes.append(f'<Script name="s{i}" code={quoteattr(script(rng))}/>')
        elif roll < 0.8:
            nodes.append(f'<ScriptCondition name="c{i}" code={quoteattr(expression(rng, 2, True))}/>')
        else:
            pre, post = quoteattr(expression(rng, 2, True)), quoteattr(script(rng))
            nodes.append(f'<AlwaysSuccess name="a{i}" {rng.choice(PRE)}={pre} _post={post}/>')
    body = "".join(nodes)
    return (
        f'<root BTCPP_format="4" main_tree_to_execute="M"><BehaviorTree ID="M"><Sequence>{body}'
        "</Sequence></BehaviorTree></root>"
    )
