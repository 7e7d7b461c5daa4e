"""Liveness of the components whose behaviors an executor loaded, from their heartbeats.

Pure state with an injected clock: the ROS subscription (in `context`) feeds `observe`, the tick
loop asks `failure` (behavior calls fail fast) and `degraded` (the `LibraryDegraded` condition).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from coral.sdk import topics

RESTARTED = "it restarted (a new process; its state is lost)"


@dataclass
class _Seen:
    last_beat: float
    stopping: bool
    instance: str
    restarted_at: float | None = None
    told: bool = False
    """A call into the restarted component has failed for it: the tree has been told."""


class HealthMonitor:
    """Remembers each component's last heartbeat; a component is degraded once it was seen alive
    and then fell silent for `timeout_s`, announced it is stopping, or came back as a new process.
    A new process stays degraded for `restart_s` after its first beat and until a call into it
    failed for it (`refuse_call`): the new process lost the old one's state, and the tree must
    learn it through a failed behavior, which its fallback can handle, however long it takes the
    tree to call that component again. Never-seen components are not degraded: their calls wait
    for the service within their own timeout instead.
    """

    def __init__(
        self,
        clock: Callable[[], float],
        timeout_s: float = topics.HEARTBEAT_TIMEOUT_S,
        restart_s: float = topics.RESTART_DEGRADED_S,
    ) -> None:
        self._clock = clock
        self._timeout_s = timeout_s
        self._restart_s = restart_s
        self._seen: dict[str, _Seen] = {}
        self._lock = threading.Lock()

    def observe(self, heartbeat: topics.Heartbeat) -> None:
        now = self._clock()
        with self._lock:
            before = self._seen.get(heartbeat.component)
            restarted_at = before.restarted_at if before else None
            # A kubelet restarts a killed container within about a second, sooner than the
            # silence would be noticed; the new instance says the old one is gone.
            told = before.told if before else False
            if before and before.instance and heartbeat.instance and before.instance != heartbeat.instance:
                restarted_at, told = now, False
            self._seen[heartbeat.component] = _Seen(
                now, heartbeat.state == "stopping", heartbeat.instance, restarted_at, told
            )

    def failure(self, component: str) -> str | None:
        """Why calls into `component` must fail now, or None while it looks alive (or was never seen)."""
        with self._lock:
            seen = self._seen.get(component)
        if seen is None:
            return None
        if seen.stopping:
            return "it shut down"
        now = self._clock()
        silent_s = now - seen.last_beat
        if silent_s > self._timeout_s:
            # The timeout, not the growing silence: the reason ends up in `LibraryDegraded`'s
            # message, and a message that changed every tick would rewrite the condition (and
            # patch the CoralInstance) every tick for as long as the component stays away.
            return f"no heartbeat for over {self._timeout_s:g} s"
        if seen.restarted_at is not None and (not seen.told or now - seen.restarted_at < self._restart_s):
            return RESTARTED
        return None

    def refuse_call(self, component: str) -> str | None:
        """`failure`, for a behavior about to call `component`: the call fails with this reason. A
        restart's reason, once given, counts as told to the tree."""
        reason = self.failure(component)
        if reason == RESTARTED:
            with self._lock:
                seen = self._seen.get(component)
                if seen is not None:
                    seen.told = True
        return reason

    def state(self, component: str) -> str:
        """`unknown` (no heartbeat yet), `alive`, or `degraded`."""
        with self._lock:
            seen = component in self._seen
        if not seen:
            return "unknown"
        return "alive" if self.failure(component) is None else "degraded"

    def next_failure_at(self, components: Iterable[str]) -> float | None:
        """The earliest clock time at which one of `components`, alive now, turns silent unless
        it beats again; None when none is alive. The tick loop sleeps no longer than that, so a
        dead skillset fails its calls on time even when nothing else wakes the tree."""
        with self._lock:
            beats = [
                seen.last_beat
                for name in set(components)
                if (seen := self._seen.get(name)) and not seen.stopping
            ]
        due = [beat + self._timeout_s for beat in beats if beat + self._timeout_s >= self._clock()]
        return min(due) if due else None

    def degraded(self, components: Iterable[str]) -> dict[str, str]:
        """Component name -> reason, for each of `components` that is currently degraded."""
        reasons: dict[str, str] = {}
        for component in sorted(set(components)):
            reason = self.failure(component)
            if reason is not None:
                reasons[component] = reason
        return reasons
