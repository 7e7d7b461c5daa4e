"""Names and message layouts of the ROS topics the runtime itself uses (not the skillsets' own).

Shared by components (`coral.sdk.component`), the executor's health monitor and the call helpers,
so both ends agree without importing each other.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass

from coral_core import parsing

# Every component publishes `Heartbeat` records here; executors watch it to detect dead skillsets.
HEARTBEAT_TOPIC = "/coral/heartbeat"
# Three beats per timeout. Every beat wakes the executors and the beating component's own rclpy
# executor; at 5 a second per component those wake-ups cost a busy robot computer measurably
# (docs/architecture.md, "Where the SLAM mission's CPU goes").
HEARTBEAT_PERIOD_S = 0.5
# A component silent for this long is considered gone (several missed beats, not one slow one).
HEARTBEAT_TIMEOUT_S = 1.5
# A component that came back as a new process stays degraded this long after its first beat: a
# container restarted quicker than the heartbeat timeout lost its state all the same, and the
# condition must last long enough to be reported.
RESTART_DEGRADED_S = 5.0

# Executors publish `CancelRequest`s here when a behavior is halted with a request in flight.
CANCEL_TOPIC = "/coral/cancel"


@dataclass(frozen=True)
class Heartbeat:
    component: str
    kind: str
    state: str  # "alive" while running, "stopping" once on a clean shutdown
    pid: int
    # Random per process: tells a restarted component from the one before it even where both have
    # the same pid (pid 1 of a container).
    instance: str = ""

    def encode(self) -> str:
        return json.dumps(asdict(self), separators=(",", ":"))

    @classmethod
    def decode(cls, text: str) -> Heartbeat | None:
        try:
            raw = parsing.load_json(text)
            return cls(
                str(raw["component"]),
                str(raw["kind"]),
                str(raw["state"]),
                int(raw["pid"]),
                str(raw.get("instance", "")),
            )
        except (ValueError, KeyError, TypeError):
            return None


@dataclass(frozen=True)
class CancelRequest:
    service: str  # fully qualified service name
    requester: str  # fully qualified node name of the executor that halted the call

    def encode(self) -> str:
        return json.dumps(asdict(self), separators=(",", ":"))

    @classmethod
    def decode(cls, text: str) -> CancelRequest | None:
        try:
            raw = parsing.load_json(text)
            return cls(str(raw["service"]), str(raw["requester"]))
        except (ValueError, KeyError, TypeError):
            return None
