"""What `coral rollout` does to a CoralSystem, as a small library (also used by tests and tooling).

Pause and resume set `spec.rollout.paused`, as `kubectl rollout pause` does for a Deployment.
Resume also names the recorded health-gate failure it acknowledges in the `coral.dev/rollout-resume`
annotation, so the operator clears it and judges the robots afresh. Undo sets the
`coral.dev/rollout-undo` annotation to the revision to roll back from; the operator then targets
the revision before it until the spec makes a newer one. `report` reads `status.rollout` for
`coral rollout status`, `describe` says it as plain text.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from coral_core import names
from pydantic import ValidationError

from coral_operator.api import keys
from coral_operator.api.rollout import PrePullStatus
from coral_operator.planning.rollout_report import describe_pre_pull
from coral_operator.system_control import SystemControl


class RolloutError(Exception):
    """The rollout cannot be steered that way; the message says why."""


class RolloutControl(SystemControl):
    """Reads and steers the rollouts of one namespace."""

    error = RolloutError

    def pause(self, name: str) -> None:
        self.read(name)
        self.patch(name, {"spec": {"rollout": {"paused": True}}})

    def resume(self, name: str) -> None:
        body = self.read(name)
        patch: dict[str, Any] = {"spec": {"rollout": {"paused": False}}}
        rollout = (body.get("status") or {}).get(keys.SYSTEM_STATUS.rollout) or {}
        failed_at = (rollout.get(keys.ROLLOUT.failure) or {}).get(keys.ROLLOUT_FAILURE.time)
        if failed_at:
            patch["metadata"] = {"annotations": {names.ANNOTATION_ROLLOUT_RESUME: failed_at}}
        self.patch(name, patch)

    def undo(self, name: str) -> str:
        """Roll back from the spec's newest revision; returns that revision."""
        body = self.read(name)
        rollout = (body.get("status") or {}).get(keys.SYSTEM_STATUS.rollout) or {}
        history = rollout.get(keys.ROLLOUT.history) or []
        if not history:
            raise RolloutError(f"coralsystem/{name} has no revision yet; nothing to undo")
        newest = history[-1]
        if len(history) < 2:
            raise RolloutError(f"coralsystem/{name} has no revision before {newest} to return to")
        if (rollout.get(keys.ROLLOUT.rolled_back) or {}).get(keys.ROLLED_BACK.from_revision) == newest:
            raise RolloutError(f"coralsystem/{name} is already rolled back from revision {newest}")
        self.patch(name, {"metadata": {"annotations": {names.ANNOTATION_ROLLOUT_UNDO: newest}}})
        return str(newest)


@dataclass(frozen=True)
class Progress:
    """Where a rollout stands for someone waiting on it, like `kubectl rollout status`."""

    done: bool
    """The spec was observed and every robot taking part runs it and passes the health gate."""
    failure: str | None
    """Why waiting longer will not help (a failed health gate, a rollback); None otherwise."""
    waiting_for: str
    """What the rollout waits for, as a phrase (empty when done or failed)."""


def _generations(body: dict[str, Any]) -> tuple[int | None, int | None]:
    generation = (body.get("metadata") or {}).get("generation")
    observed = (body.get("status") or {}).get(keys.SYSTEM_STATUS.observed_generation)
    return generation, observed


def _stalled(body: dict[str, Any]) -> str | None:
    """Why the system is Stalled at the spec's generation (a refused spec, failed robots), if it is.

    A Stalled system cannot complete its rollout without a change, so waiting longer cannot help.
    """
    generation, _ = _generations(body)
    for condition in (body.get("status") or {}).get(keys.SYSTEM_STATUS.conditions) or []:
        if (
            condition.get(keys.CONDITION.type) == "Stalled"
            and condition.get(keys.CONDITION.status) == "True"
            and condition.get(keys.CONDITION.observed_generation) == generation
        ):
            message = condition.get(keys.CONDITION.message) or "Stalled"
            return f"{condition.get(keys.CONDITION.reason)}: {message}"
    return None


def _counts(rollout: dict[str, Any]) -> dict[str, int]:
    """`status.rollout.counts` by wire name, every count present; an absent count is 0."""
    counts = rollout.get(keys.ROLLOUT.counts) or {}
    return {key: int(counts.get(key, 0)) for key in keys.ROLLOUT_COUNTS}


def _failure_message(rollout: dict[str, Any]) -> str:
    return str(rollout[keys.ROLLOUT.failure].get(keys.ROLLOUT_FAILURE.message, ""))


def evaluate_progress(body: dict[str, Any]) -> Progress:
    """The rollout's progress; a status written for an older spec never counts as done."""
    generation, observed = _generations(body)
    if generation is not None and (observed is None or observed < generation):
        return Progress(False, None, f"the operator to observe generation {generation}")
    rollout = (body.get("status") or {}).get(keys.SYSTEM_STATUS.rollout) or {}
    if not rollout:
        stalled = _stalled(body)
        if stalled:
            return Progress(False, f"the system is Stalled ({stalled})", "")
        return Progress(False, None, "the operator's first rollout report")
    if rollout.get(keys.ROLLOUT.failure):
        return Progress(False, f"health gate failed: {_failure_message(rollout)}", "")
    back = rollout.get(keys.ROLLOUT.rolled_back)
    if back:
        left, right = back.get(keys.ROLLED_BACK.from_revision), back.get(keys.ROLLED_BACK.to_revision)
        return Progress(
            False,
            f"rolled back from revision {left} to {right} ({back.get(keys.ROLLED_BACK.reason, 'Undo')}); "
            "the spec's revision does not run until the spec changes",
            "",
        )
    stalled = _stalled(body)
    if stalled:
        return Progress(False, f"the system is Stalled ({stalled})", "")
    if rollout.get(keys.ROLLOUT.complete):
        return Progress(True, None, "")
    if rollout.get(keys.ROLLOUT.paused):
        return Progress(False, None, "the rollout to be resumed (coral rollout resume)")
    counts = _counts(rollout)
    waiting = (
        f"{counts[keys.ROLLOUT_COUNTS.total] - counts[keys.ROLLOUT_COUNTS.healthy]} of "
        f"{counts[keys.ROLLOUT_COUNTS.total]} robots "
        f"to run revision {rollout.get(keys.ROLLOUT.revision)} and pass the health gate"
    )
    if rollout.get(keys.ROLLOUT.waiting_for):
        waiting += f" ({', '.join(rollout[keys.ROLLOUT.waiting_for])})"
    return Progress(False, None, waiting)


def finished(body: dict[str, Any]) -> bool:
    """Nothing more will happen without a human: the rollout completed or failed."""
    progress = evaluate_progress(body)
    return progress.done or progress.failure is not None


COUNT_COLUMNS = (
    (keys.ROLLOUT_COUNTS.total, "ROBOTS"),
    (keys.ROLLOUT_COUNTS.updated, "UPDATED"),
    (keys.ROLLOUT_COUNTS.healthy, "HEALTHY"),
    (keys.ROLLOUT_COUNTS.unavailable, "UNAVAILABLE"),
    (keys.ROLLOUT_COUNTS.max_unavailable, "MAX UNAVAILABLE"),
    (keys.ROLLOUT_COUNTS.locked, "LOCKED"),
    (keys.ROLLOUT_COUNTS.offline, "OFFLINE"),
)
"""The robot counts of `status.rollout.counts` and their column headers in `coral rollout status`."""


@dataclass(frozen=True)
class Report:
    """What `coral rollout status` says, before it is drawn as text or on a terminal.

    Each line of `notes` and the `verdict` carry a tone, `ok`, `warn`, `bad` or `""`, that a
    terminal shows as a colour.
    """

    title: str
    spec: str
    """Spec and target revision, generations, and how many robots run the target ("" before the
    first rollout report)."""
    counts: dict[str, int]
    notes: list[tuple[str, str]]
    verdict: tuple[str, str]


def report(body: dict[str, Any]) -> Report:
    """`status.rollout` of a CoralSystem as a `Report`: target and current revision, counts, what it
    waits for, and whether it is complete, failed or in progress."""
    name = body["metadata"]["name"]
    status = body.get("status") or {}
    rollout = status.get(keys.SYSTEM_STATUS.rollout)
    generation, observed = _generations(body)
    progress = evaluate_progress(body)
    if not rollout:
        revision = status.get(keys.SYSTEM_STATUS.revision, "unknown")
        return Report(
            title=f"coralsystem/{name}: no rollout reported yet (revision {revision})",
            spec="",
            counts={},
            notes=[],
            verdict=(f"waiting for {progress.waiting_for}", "bad" if progress.failure else "warn"),
        )
    every_count = _counts(rollout)
    counts = {key: every_count[key] for key, _header in COUNT_COLUMNS}
    history = rollout.get(keys.ROLLOUT.history) or []
    target = rollout.get(keys.ROLLOUT.revision)
    previous = rollout.get(keys.ROLLOUT.previous_revision)
    notes: list[tuple[str, str]] = []
    canary = rollout.get(keys.ROLLOUT.canary)
    if canary:
        healthy, robots = canary.get(keys.CANARY.healthy, 0), canary.get(keys.CANARY.robots, 0)
        notes.append(
            (
                f"canary: {healthy} of {robots} healthy"
                + (", promoted" if canary.get(keys.CANARY.promoted) else "")
                + (f", healthy since {since}" if (since := canary.get(keys.CANARY.healthy_since)) else ""),
                "",
            )
        )
    if rollout.get(keys.ROLLOUT.rolled_back):
        back = rollout[keys.ROLLOUT.rolled_back]
        left, right = back.get(keys.ROLLED_BACK.from_revision), back.get(keys.ROLLED_BACK.to_revision)
        notes.append((f"rolled back from {left} to {right} ({back.get(keys.ROLLED_BACK.reason)})", "warn"))
    if rollout.get(keys.ROLLOUT.failure):
        notes.append((f"failure: {_failure_message(rollout)}", "bad"))
    if rollout.get(keys.ROLLOUT.pre_pull):
        notes.extend(_pre_pull_notes(rollout[keys.ROLLOUT.pre_pull]))
    if rollout.get(keys.ROLLOUT.waiting_for):
        notes.append((f"waiting for: {', '.join(rollout[keys.ROLLOUT.waiting_for])}", ""))
    if progress.done:
        verdict = (f"complete: {rollout.get(keys.ROLLOUT.message, '')}", "ok")
    elif progress.failure:
        verdict = (f"failed: {progress.failure}", "bad")
    else:
        message = rollout.get(keys.ROLLOUT.message, "")
        verdict = (f"in progress, waiting for {progress.waiting_for}: {message}", "warn")
    return Report(
        title=f"coralsystem/{name} revision {target} (previous {previous or 'none'})",
        spec=(
            f"spec revision {history[-1] if history else target}, generation {generation} "
            f"(observed {observed}); target revision {target}; {counts[keys.ROLLOUT_COUNTS.updated]} of "
            f"{counts[keys.ROLLOUT_COUNTS.total]} robots run it"
        ),
        counts=counts,
        notes=notes,
        verdict=verdict,
    )


def _pre_pull_notes(written: dict[str, Any]) -> list[tuple[str, str]]:
    """The pull progress, then each failed robot with the kubelet's message."""
    try:
        pre_pull = PrePullStatus.model_validate(written)
    except ValidationError:
        return [("pre-pull: unreadable status", "warn")]
    tone = "bad" if pre_pull.failed else ("ok" if not pre_pull.pulling else "warn")
    notes = [(f"pre-pull of revision {pre_pull.revision}: {describe_pre_pull(pre_pull)}", tone)]
    notes += [(f"pull failed on {f.robot}: {f.message}", "bad") for f in pre_pull.failures]
    return notes


def describe(body: dict[str, Any]) -> str:
    """`coral rollout status` as plain lines of text (`report` is what it says)."""
    said = report(body)
    lines = [said.title]
    if said.spec:
        healthy, updated, total, unavailable, most, locked, offline = (
            said.counts[key]
            for key in (
                keys.ROLLOUT_COUNTS.healthy,
                keys.ROLLOUT_COUNTS.updated,
                keys.ROLLOUT_COUNTS.total,
                keys.ROLLOUT_COUNTS.unavailable,
                keys.ROLLOUT_COUNTS.max_unavailable,
                keys.ROLLOUT_COUNTS.locked,
                keys.ROLLOUT_COUNTS.offline,
            )
        )
        lines += [
            f"  {said.spec}",
            f"  robots: {healthy} healthy, {updated} updated of {total}; "
            f"{unavailable} unavailable (max {most}), {locked} "
            f"locked by running trees, {offline} offline",
        ]
    lines += [f"  {text}" for text, _tone in [*said.notes, said.verdict]]
    return "\n".join(lines)
