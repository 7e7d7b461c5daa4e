"""Exec readiness probes, evaluated by the runner as the kubelet would, without blocking its loop.

`pods.PodWorker` owns one `Probe` per container that declares a `readinessProbe`; each `step`
starts the probe command when its period is due (inside the robot's network, with the container's
environment and paths) and collects the result of the previous run, killing it after its timeout.
Only `exec` probes are supported: components here are local processes, not servers with ports
the runner would know how to reach.
"""

from __future__ import annotations

import os
import signal
import subprocess
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from coral_testbed.runner import podspec


@dataclass
class Probe:
    argv: list[str]
    env: dict[str, str]
    initial_delay: float = 0.0
    period: float = 10.0
    timeout: float = 1.0
    success_threshold: int = 1
    failure_threshold: int = 3
    ready: bool = False
    _process: subprocess.Popen[bytes] | None = field(default=None, repr=False)
    _started: float = 0.0
    _next: float = 0.0
    _successes: int = 0
    _failures: int = 0

    @classmethod
    def from_spec(
        cls, spec: Mapping[str, Any], paths: podspec.PathMap, env: Mapping[str, str], container: str
    ) -> Probe:
        command = (spec.get("exec") or {}).get("command")
        if not command:
            kinds = sorted(k for k in spec if k in ("httpGet", "tcpSocket", "grpc"))
            raise podspec.ContainerConfigError(
                f"containers[{container}].readinessProbe: only exec probes are supported, got {kinds}"
            )
        return cls(
            argv=[paths.rewrite(podspec.expand(str(part), env)) for part in command],
            env=dict(env),
            initial_delay=float(spec.get("initialDelaySeconds", 0)),
            period=float(spec.get("periodSeconds", 10)),
            timeout=float(spec.get("timeoutSeconds", 1)),
            success_threshold=int(spec.get("successThreshold", 1)),
            failure_threshold=int(spec.get("failureThreshold", 3)),
        )

    def reset(self, now: float) -> None:
        """The container (re)started: not ready until the probe passes again."""
        self.cancel()
        self.ready = False
        self._successes = self._failures = 0
        self._next = now + self.initial_delay

    def step(self, prefix: list[str], now: float) -> None:
        if self._process is not None:
            code = self._process.poll()
            if code is None and now - self._started < self.timeout:
                return
            if code is None:
                self.cancel()
                code = -1
            self._process = None
            self._record(code == 0)
        if now >= self._next:
            self._next = now + self.period
            try:
                self._process = subprocess.Popen(
                    prefix + self.argv,
                    env=self.env,
                    stdin=subprocess.DEVNULL,
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                    start_new_session=True,
                )
                self._started = now
            except OSError:
                self._record(False)

    def _record(self, passed: bool) -> None:
        if passed:
            self._successes += 1
            self._failures = 0
            if self._successes >= self.success_threshold:
                self.ready = True
        else:
            self._failures += 1
            self._successes = 0
            if self._failures >= self.failure_threshold:
                self.ready = False

    def cancel(self) -> None:
        if self._process is not None and self._process.poll() is None:
            try:
                os.killpg(self._process.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            self._process.wait()
        self._process = None
