"""The rollout part of a CoralSystem's status (`status.rollout`; docs/architecture.md, "Rollouts").

Counts and a few names only, never a per-robot list, so the status stays small at thousands of
robots. Written by the system handler from `planning.rollout`'s decision; read back by the same
planner on the next pass (it carries the canary clock and a failure across operator restarts)
and by `coral rollout status`.
"""

from __future__ import annotations

from typing import Literal

from coral_core.wire import CamelModel
from pydantic import Field

MAX_NAMED = 10
"""At most this many robot names appear in any list of the rollout status."""


class RolloutCounts(CamelModel):
    """Where the matched robots stand in the rollout."""

    total: int = 0
    """Robots taking part (matched robots with a CoralInstance)."""
    updated: int = 0
    """Robots running the target revision."""
    healthy: int = 0
    """Robots running the target revision whose instance is Ready and whose tree has not failed."""
    unavailable: int = 0
    """Robots counted against `maxUnavailable` right now."""
    max_unavailable: int = 0
    """`maxUnavailable` resolved to a count of robots."""
    locked: int = 0
    """Robots held at their revision because their tree is RUNNING a mission (the update lock)."""
    offline: int = 0
    """Robots not yet updated whose Node is not Ready."""
    failed: int = 0
    """Robots on the target revision that failed the health gate."""


class CanaryStatus(CamelModel):
    """Progress of the canary robots."""

    robots: int = 0
    """Canary robots among the matched ones."""
    updated: int = 0
    """Canaries on the target revision."""
    healthy: int = 0
    """Canaries on the target revision passing the health gate."""
    healthy_since: str | None = None
    """Since when every canary has passed the health gate (RFC 3339); the hold time counts from here."""
    promoted: bool = False
    """The canaries held healthy for the hold time; the rest of the fleet follows."""


class RolloutFailure(CamelModel):
    """A failed health gate that stopped the rollout of one revision."""

    revision: str
    """The revision that failed."""
    robots: list[str] = Field(default_factory=list, max_length=MAX_NAMED)
    """Some of the robots that failed."""
    message: str = ""
    """What failed, as a sentence."""
    time: str | None = None
    """When the failure was seen (RFC 3339)."""


class RolledBack(CamelModel):
    """The fleet is being returned to an earlier revision."""

    from_revision: str
    """The revision rolled back from; the rollback lasts while the spec asks for this revision."""
    to_revision: str
    """The revision robots return to."""
    reason: Literal["Undo", "HealthGateFailed"] = "Undo"
    """`Undo` (asked for with `coral rollout undo`) or `HealthGateFailed` (`onFailure: Rollback`)."""


class PullFailure(CamelModel):
    """A robot whose pre-pull failed, with the kubelet's message."""

    robot: str
    """The robot."""
    message: str = ""
    """Why its images are not there (`ErrImagePull: ...`, or the deadline)."""


class PrePullStatus(CamelModel):
    """Progress of pulling the target revision's images on the robots to move (`spec.rollout.prePull`)."""

    revision: str
    """The revision whose images are pulled."""
    robots: int = 0
    """Online robots that need the images (not yet on the revision)."""
    pulled: int = 0
    """Of those, robots whose runtime has every image."""
    pulling: int = 0
    """Robots still pulling."""
    failed: int = 0
    """Robots whose pull failed or did not finish before the deadline; they do not move."""
    started: str | None = None
    """When pulling this revision started (RFC 3339); the deadline counts from here."""
    released: bool = False
    """The wave may start: every robot pulled or failed, or the deadline passed (`BeforeRollout`)."""
    failures: list[PullFailure] = Field(default_factory=list, max_length=MAX_NAMED)
    """Some of the failed robots, with the kubelet's message."""


class RolloutStatus(CamelModel):
    """Progress of the rollout of the newest revision over the fleet."""

    revision: str | None = None
    """The revision robots are being moved to (the spec's newest, or an earlier one when rolled back)."""
    previous_revision: str | None = None
    """The revision before it in the history, which `undo` and `onFailure: Rollback` return to."""
    history: list[str] = Field(default_factory=list, max_length=32)
    """Known revisions, oldest first (their templates are kept as ControllerRevisions)."""
    complete: bool = False
    """Every robot taking part (offline robots excepted, unless `offlineRobots: Wait`) runs the target
    revision and passes the health gate."""
    paused: bool = False
    """No robot is moved: `spec.rollout.paused`, or a failure with `onFailure: Pause`."""
    counts: RolloutCounts = Field(default_factory=RolloutCounts)
    """Robot counts."""
    canary: CanaryStatus | None = None
    """Canary progress, when `spec.rollout.canary` is set."""
    failure: RolloutFailure | None = None
    """The health-gate failure that paused the rollout; `coral rollout resume` clears it."""
    rolled_back: RolledBack | None = None
    """Set while the fleet returns to an earlier revision."""
    pre_pull: PrePullStatus | None = None
    """Image pre-pull progress, when `spec.rollout.prePull` is set."""
    waiting_for: list[str] = Field(default_factory=list, max_length=MAX_NAMED)
    """Some of the robots the rollout waits for (running trees, offline robots), for humans."""
    message: str = ""
    """One sentence saying where the rollout stands."""
