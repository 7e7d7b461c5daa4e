"""Hooks compared between real BT.CPP's Groot2Publisher and coral_core.bt's through one pyzmq client:
replace hooks, breakpoints unlocked with SUCCESS, FAILURE or SKIPPED (some with `once` or
`remove_when_done`), the hooks dump, and the heartbeat release (a breakpoint whose client went
silent lets the tick go on). Each engine runs the same script; the traces must be equal.

Only pre-tick hooks are compared: BT.CPP 4.8.2 installs every hook before the tick whatever its
position (4.10, which coral follows, has real post-tick hooks; their own tests cover them).
"""

from __future__ import annotations

import random
import time
from dataclasses import dataclass, field
from typing import Any

from bt_groot2_differential import fulltree_shape
from bt_groot2_engines import BTCPP, CORAL, EngineHost, LoadRequest
from coral_core.bt.groot2 import protocol as p
from coral_core.bt.groot2.client import Groot2Client

UNLOCKS = ("SUCCESS", "FAILURE", "SKIPPED")
SUB_SETTLE_S = 0.1
# A held tick ends by an unlock, or 5 s after the client's last request (the heartbeat).
TICK_LIMIT_S = 60.0
# How long no breakpoint message may arrive before a tick's notifications count as all read: the
# publisher sends them as the tick runs, and a busy machine (the kind lane beside this one under
# `make test`) delays their delivery by more than a tick's length.
QUIET_S = 0.1
QUIET_ROUND_TRIPS = 5


@dataclass
class HookScript:
    """What the client does: hooks to insert, then per breakpoint reached an unlock (cycled)."""

    hooks: list[p.HookRecord]
    unlocks: list[tuple[str, bool]] = field(default_factory=lambda: [("SKIPPED", False)])
    ticks: int = 6
    silent_heartbeat: bool = False  # never unlock: wait for the heartbeat to release the breakpoint
    max_hits: int = 40


def uids_of(shape: Any) -> list[int]:
    out: list[int] = []

    def walk(node: Any) -> None:
        tag, attrs, children = node
        values = dict(attrs)
        if "_uid" in values:
            out.append(int(values["_uid"]))
        for child in children:
            walk(child)

    for tree in shape:
        walk(tree)
    return sorted(out)


def _drain(client: Groot2Client, quiet_s: float) -> list[int]:
    hits = []
    while (uid := client.next_breakpoint(quiet_s)) is not None:
        hits.append(uid)
    return hits


def run_script(host: EngineHost, request: LoadRequest, script: HookScript) -> list[Any]:
    verdict, port = host.load(request)
    if verdict != "LOADED":
        return [verdict]
    trace: list[Any] = []
    hung = False
    try:
        with Groot2Client(port=port, timeout_s=10) as client:
            client.next_breakpoint(0)  # subscribe now: a PUB drops what no subscriber asked for yet
            time.sleep(SUB_SETTLE_S)
            client.insert_hooks(script.hooks)
            trace.append(("hooks", sorted(tuple(sorted(h.items())) for h in client.hooks())))
            client.start_recording()
            unlock_index = 0
            for _ in range(script.ticks):
                host.start_tick()
                hits: list[Any] = []
                done = None
                deadline = time.monotonic() + TICK_LIMIT_S
                while done is None:
                    if time.monotonic() > deadline:
                        raise TimeoutError(f"the {host.engine} tick did not end in {TICK_LIMIT_S} s: {hits}")
                    done = host.tick_done(0.0)
                    if done is not None:
                        break
                    uid = client.next_breakpoint(0.01)
                    if uid is None:
                        continue
                    breakpoint_hit = any(
                        h.uid == uid and h.mode == p.BREAKPOINT and h.enabled for h in script.hooks
                    )
                    if script.silent_heartbeat or not breakpoint_hit or len(hits) >= script.max_hits:
                        hits.append(("passed", uid))
                        continue
                    hits.append(("held", uid, client.status()))
                    status, remove = script.unlocks[unlock_index % len(script.unlocks)]
                    unlock_index += 1
                    # A replace hook on the same node may have reached here first: then no
                    # breakpoint waits, and the unlock still edits the hook.
                    client.unlock(uid, status, p.PRE, remove)
                    hits.append(("unlocked", status, remove))
                # A request's round trip goes through the engine's process after the notifications it
                # sent during the tick: how long it takes says how slow delivery is right now.
                asked = time.monotonic()
                statuses = client.status()
                quiet_s = max(QUIET_S, QUIET_ROUND_TRIPS * (time.monotonic() - asked))
                hits += [("passed", uid) for uid in _drain(client, quiet_s)]
                kind, result = done
                trace.append(("tick", result if kind == "status" else "ERROR", hits))
                trace.append(("status", statuses))
                trace.append(("transitions", [(uid, st) for _t, uid, st in client.transitions()]))
                if script.silent_heartbeat:
                    time.sleep(0.1)  # the requests above brought the heartbeat back: let both see it
                trace.append(("hooks", sorted(tuple(sorted(h.items())) for h in client.hooks())))
                if kind != "status":
                    break
            client.remove_all_hooks()
            trace.append(("hooks", client.hooks()))
    except TimeoutError:
        hung = True
        raise
    finally:
        if hung:
            host.restart()
        else:
            host.drop()
    return trace


def random_script(seed: int, uids: list[int]) -> HookScript:
    rng = random.Random(seed)
    hooks = []
    for uid in rng.sample(uids, min(len(uids), rng.choice((1, 1, 2)))):
        mode = rng.choice((p.BREAKPOINT, p.REPLACE))
        hooks.append(
            p.HookRecord(
                uid=uid,
                position=p.PRE,
                mode=mode,
                once=rng.random() < 0.3,
                desired_status=rng.choice((2, 3, 4)) if mode == p.REPLACE else 4,
            )
        )
    unlocks = [(rng.choice(UNLOCKS), rng.random() < 0.2) for _ in range(4)]
    return HookScript(hooks, unlocks)


@dataclass
class HookReport:
    runs: int = 0
    agreeing: int = 0
    held: int = 0
    reference_hangs: int = 0
    mismatches: list[str] = field(default_factory=list)


def compare_hooks(cases: list[tuple[str, LoadRequest, Any]], report: HookReport) -> HookReport:
    """`cases` are (label, request, script or a function from the tree's uids to a script)."""
    theirs_host, ours_host = EngineHost(BTCPP, 23000), EngineHost(CORAL, 43000)
    try:
        for label, request, script in cases:
            if callable(script):
                verdict, port = theirs_host.load(request)
                if verdict != "LOADED":
                    continue
                with Groot2Client(port=port, timeout_s=10) as client:
                    shape, _models = fulltree_shape(client.fulltree())
                theirs_host.drop()
                script = script(uids_of(shape))
            try:
                theirs = run_script(theirs_host, request, script)
            except TimeoutError:
                # BT.CPP 4.8's heartbeat thread acts only on a change it sees, waking every 10 ms:
                # on a saturated machine it can sleep through a burst of requests and the delay
                # after it, so hooks inserted meanwhile (enabled) hold a silent client's breakpoint
                # for good. The reference is asked again in a new process; coral's engine, which
                # checks the heartbeat as it answers each request, gets no second try.
                report.reference_hangs += 1
                theirs = run_script(theirs_host, request, script)
            ours = run_script(ours_host, request, script)
            report.runs += 1
            report.held += sum(1 for step in theirs if step[0] == "tick" for h in step[2] if h[0] == "held")
            if theirs == ours:
                report.agreeing += 1
            else:
                where = (
                    next(i for i, (a, b) in enumerate(zip(theirs, ours, strict=False)) if a != b)
                    if any(a != b for a, b in zip(theirs, ours, strict=False))
                    else min(len(theirs), len(ours))
                )
                report.mismatches.append(
                    f"{label}: step {where}: BT.CPP {str(theirs[where : where + 1])[:400]} vs coral "
                    f"{str(ours[where : where + 1])[:400]}\n  {request.xml[:400]}"
                )
    finally:
        theirs_host.close()
        ours_host.close()
    return report
