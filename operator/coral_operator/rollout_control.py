"""What `coral rollout` does to a CoralSystem, as a small library (also used by tests and tooling).

Pause and resume set `spec.rollout.paused`, as `kubectl rollout pause` does for a Deployment.
Resume also names the recorded health-gate failure it acknowledges in the `coral.dev/rollout-resume`
annotation, so the operator clears it and judges the robots afresh. Undo sets the
`coral.dev/rollout-undo` annotation to the revision to roll back from; the operator then targets
the revision before it until the spec makes a newer one. `report` reads `status.rollout` for
`coral rollout status`, `describe` says it as plain text.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

from kubernetes import client as k8s
from kubernetes import config as k8s_config
from kubernetes.client.exceptions import ApiException

GROUP, VERSION, PLURAL = "coral.dev", "v1alpha1", "coralsystems"
UNDO_ANNOTATION = "coral.dev/rollout-undo"
RESUME_ANNOTATION = "coral.dev/rollout-resume"


class RolloutError(Exception):
    """The rollout cannot be steered that way; the message says why."""


class RolloutControl:
    """Reads and steers the rollouts of one namespace."""

    def __init__(self, api_client: k8s.ApiClient, namespace: str) -> None:
        self.custom = k8s.CustomObjectsApi(api_client)
        self.namespace = namespace

    @classmethod
    def from_kubeconfig(cls, namespace: str) -> RolloutControl:
        try:
            k8s_config.load_incluster_config()
        except k8s_config.ConfigException:
            # Read $KUBECONFIG now: the client's default location is fixed when it is imported.
            k8s_config.load_kube_config(config_file=os.environ.get("KUBECONFIG"))
        return cls(k8s.ApiClient(), namespace)

    def read(self, name: str) -> dict[str, Any]:
        try:
            return self.custom.get_namespaced_custom_object(GROUP, VERSION, self.namespace, PLURAL, name)
        except ApiException as error:
            if error.status == 404:
                raise RolloutError(f"coralsystem/{name} not found in namespace {self.namespace}") from error
            raise

    def _patch(self, name: str, body: dict[str, Any]) -> None:
        self.custom.patch_namespaced_custom_object(
            GROUP, VERSION, self.namespace, PLURAL, name, body, _content_type="application/merge-patch+json"
        )

    def pause(self, name: str) -> None:
        self.read(name)
        self._patch(name, {"spec": {"rollout": {"paused": True}}})

    def resume(self, name: str) -> None:
        body = self.read(name)
        patch: dict[str, Any] = {"spec": {"rollout": {"paused": False}}}
        failure = ((body.get("status") or {}).get("rollout") or {}).get("failure")
        if failure and failure.get("time"):
            patch["metadata"] = {"annotations": {RESUME_ANNOTATION: failure["time"]}}
        self._patch(name, patch)

    def undo(self, name: str) -> str:
        """Roll back from the spec's newest revision; returns that revision."""
        body = self.read(name)
        rollout = (body.get("status") or {}).get("rollout") or {}
        history = rollout.get("history") or []
        if not history:
            raise RolloutError(f"coralsystem/{name} has no revision yet; nothing to undo")
        newest = history[-1]
        if len(history) < 2:
            raise RolloutError(f"coralsystem/{name} has no revision before {newest} to return to")
        if (rollout.get("rolledBack") or {}).get("fromRevision") == newest:
            raise RolloutError(f"coralsystem/{name} is already rolled back from revision {newest}")
        self._patch(name, {"metadata": {"annotations": {UNDO_ANNOTATION: newest}}})
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
    observed = (body.get("status") or {}).get("observedGeneration")
    return generation, observed


def _stalled(body: dict[str, Any]) -> str | None:
    """Why the system is Stalled at the spec's generation (a refused spec, failed robots), if it is.

    A Stalled system cannot complete its rollout without a change, so waiting longer cannot help.
    """
    generation, _ = _generations(body)
    for condition in (body.get("status") or {}).get("conditions") or []:
        if (
            condition.get("type") == "Stalled"
            and condition.get("status") == "True"
            and condition.get("observedGeneration") == generation
        ):
            return f"{condition.get('reason')}: {condition.get('message') or 'Stalled'}"
    return None


def evaluate_progress(body: dict[str, Any]) -> Progress:
    """The rollout's progress; a status written for an older spec never counts as done."""
    generation, observed = _generations(body)
    if generation is not None and (observed is None or observed < generation):
        return Progress(False, None, f"the operator to observe generation {generation}")
    rollout = (body.get("status") or {}).get("rollout") or {}
    if not rollout:
        stalled = _stalled(body)
        if stalled:
            return Progress(False, f"the system is Stalled ({stalled})", "")
        return Progress(False, None, "the operator's first rollout report")
    if rollout.get("failure"):
        return Progress(False, f"health gate failed: {rollout['failure'].get('message', '')}", "")
    back = rollout.get("rolledBack")
    if back:
        return Progress(
            False,
            f"rolled back from revision {back.get('fromRevision')} to {back.get('toRevision')} "
            f"({back.get('reason', 'Undo')}); the spec's revision does not run until the spec changes",
            "",
        )
    stalled = _stalled(body)
    if stalled:
        return Progress(False, f"the system is Stalled ({stalled})", "")
    if rollout.get("complete"):
        return Progress(True, None, "")
    if rollout.get("paused"):
        return Progress(False, None, "the rollout to be resumed (coral rollout resume)")
    counts = rollout.get("counts") or {}
    waiting = (
        f"{counts.get('total', 0) - counts.get('healthy', 0)} of {counts.get('total', 0)} robots "
        f"to run revision {rollout.get('revision')} and pass the health gate"
    )
    if rollout.get("waitingFor"):
        waiting += f" ({', '.join(rollout['waitingFor'])})"
    return Progress(False, None, waiting)


def finished(body: dict[str, Any]) -> bool:
    """Nothing more will happen without a human: the rollout completed or failed."""
    progress = evaluate_progress(body)
    return progress.done or progress.failure is not None


COUNT_COLUMNS = (
    ("total", "ROBOTS"),
    ("updated", "UPDATED"),
    ("healthy", "HEALTHY"),
    ("unavailable", "UNAVAILABLE"),
    ("maxUnavailable", "MAX UNAVAILABLE"),
    ("locked", "LOCKED"),
    ("offline", "OFFLINE"),
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
    rollout = status.get("rollout")
    generation, observed = _generations(body)
    progress = evaluate_progress(body)
    if not rollout:
        revision = status.get("revision", "unknown")
        return Report(
            title=f"coralsystem/{name}: no rollout reported yet (revision {revision})",
            spec="",
            counts={},
            notes=[],
            verdict=(f"waiting for {progress.waiting_for}", "bad" if progress.failure else "warn"),
        )
    counts = {key: int((rollout.get("counts") or {}).get(key, 0)) for key, _header in COUNT_COLUMNS}
    history = rollout.get("history") or []
    target = rollout.get("revision")
    notes: list[tuple[str, str]] = []
    canary = rollout.get("canary")
    if canary:
        notes.append(
            (
                f"canary: {canary.get('healthy', 0)} of {canary.get('robots', 0)} healthy"
                + (", promoted" if canary.get("promoted") else "")
                + (f", healthy since {canary['healthySince']}" if canary.get("healthySince") else ""),
                "",
            )
        )
    if rollout.get("rolledBack"):
        back = rollout["rolledBack"]
        notes.append(
            (
                f"rolled back from {back.get('fromRevision')} to {back.get('toRevision')} "
                f"({back.get('reason')})",
                "warn",
            )
        )
    if rollout.get("failure"):
        notes.append((f"failure: {rollout['failure'].get('message', '')}", "bad"))
    if rollout.get("waitingFor"):
        notes.append((f"waiting for: {', '.join(rollout['waitingFor'])}", ""))
    if progress.done:
        verdict = (f"complete: {rollout.get('message', '')}", "ok")
    elif progress.failure:
        verdict = (f"failed: {progress.failure}", "bad")
    else:
        verdict = (f"in progress, waiting for {progress.waiting_for}: {rollout.get('message', '')}", "warn")
    return Report(
        title=f"coralsystem/{name} revision {target} (previous {rollout.get('previousRevision') or 'none'})",
        spec=(
            f"spec revision {history[-1] if history else target}, generation {generation} "
            f"(observed {observed}); target revision {target}; {counts['updated']} of {counts['total']} "
            "robots run it"
        ),
        counts=counts,
        notes=notes,
        verdict=verdict,
    )


def describe(body: dict[str, Any]) -> str:
    """`coral rollout status` as plain lines of text (`report` is what it says)."""
    said = report(body)
    lines = [said.title]
    if said.spec:
        counts = said.counts
        lines += [
            f"  {said.spec}",
            f"  robots: {counts['healthy']} healthy, {counts['updated']} updated of {counts['total']}; "
            f"{counts['unavailable']} unavailable (max {counts['maxUnavailable']}), {counts['locked']} "
            f"locked by running trees, {counts['offline']} offline",
        ]
    lines += [f"  {text}" for text, _tone in [*said.notes, said.verdict]]
    return "\n".join(lines)
