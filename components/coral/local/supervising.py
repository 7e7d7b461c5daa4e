"""Runs a Coral project's components as local processes: ordered start, readiness, logs, shutdown.

Order (the paper's): every driver, then (once drivers are ready) every skillset, then (once
skillsets are ready) every executor. A driver or skillset is ready when its readiness marker
`<plugins>/<name>/ready` exists; a transient driver that already exited 0 counts as done. The run
ends when every executor has exited; its exit code is the executors' (0 only if every tree
succeeded). An unexpected exit of a non-transient driver or skillset is reported and ends the run
with EXIT_COMPONENT_FAILED. SIGINT/SIGTERM stop the components in reverse order (SIGINT to each
process group, then SIGKILL after a grace period) and end the run with 128 + the signal number.
Called by `coral.local.running`.
"""

from __future__ import annotations

import os
import signal
import subprocess
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from coral_core.compose import Project, Service

from coral.local import components, console, state
from coral.stop_signals import relay_stop_signals

EXIT_COMPONENT_FAILED = 3
EXIT_NOT_READY = 4
EXIT_BAD_INPUT = 2
# The supervisor's loops stay hand-written rather than tenacity retries: each pass reacts to
# several things at once (a signal, an unexpected exit, each child's readiness or timeout).
POLL_S = 0.05
# While the executors run, the loop only refreshes the tree view and watches for exits: a slower
# pace there leaves the CPU to the mission (at 20 Hz it cost about 40 ms of CPU a second).
WATCH_S = 0.2
STOP_GRACE_S = 10.0


@dataclass
class Child:
    service: Service
    record: state.ComponentRecord
    process: subprocess.Popen[bytes]
    pump: threading.Thread
    started_at: float
    status: console.StatusTail | None = None
    view: console.TreeView = field(default_factory=console.TreeView)


class Supervisor:
    def __init__(
        self,
        project: Project,
        run: state.RunRecord,
        out: console.Console,
        *,
        output_dir: Path,
        extra_env: dict[str, str] | None = None,
    ) -> None:
        self.project = project
        self.run = run
        self.out = out
        self.output_dir = output_dir
        self.extra_env = extra_env or {}
        self.children: list[Child] = []
        self.stop_signal: int | None = None
        self.stopping = threading.Event()
        self.plugins = run.folder / "plugins"
        self.known = components.installed_components()

    # Signals.
    def install_signal_handlers(self) -> None:
        def stopped(signum: int) -> None:
            if self.stop_signal is None:
                self.stop_signal = signum
            self.stopping.set()

        relay_stop_signals(stopped)

    # Starting.
    def _environment(self, service: Service) -> dict[str, str]:
        env = {**os.environ, **self.extra_env, **service.environment}
        env.setdefault("CORAL_OUTPUT_DIR", str(self.output_dir))
        env["CORAL_RUN_HANDLE"] = self.run.handle
        env["PYTHONUNBUFFERED"] = "1"
        return env

    def start(self, service: Service) -> Child:
        record = self.run.component(service.name)
        paths = components.Paths(
            plugins=self.plugins,
            output=self.output_dir,
            status_jsonl=self.run.folder / f"status-{service.name}.jsonl",
        )
        argv = components.command_for(self.project, service, paths, self.known)
        log_path = self.run.folder / f"{service.name}.log"
        # Each component leads a process group of its own, so a stop signals it and whatever it
        # started, but stays in the supervisor's session. The kernel's autogroup scheduler gives
        # each session one share of a loaded CPU: a session per component gave the single-threaded
        # bag player as much CPU as the SLAM skillset's registration threads together, and the
        # mission ran about a tenth slower (docs/architecture.md, "Where the SLAM mission's CPU goes").
        process = subprocess.Popen(
            argv,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            env=self._environment(service),
            cwd=str(self.project.root),
            process_group=0,
        )
        pump = threading.Thread(target=self._pump, args=(service.name, process.stdout, log_path), daemon=True)
        pump.start()
        record.state, record.pid, record.log, record.command = "starting", process.pid, str(log_path), argv
        child = Child(service, record, process, pump, time.monotonic())
        if service.role == "executor":
            child.status = console.StatusTail(paths.status_jsonl)
            if self.project.tree is not None:
                child.view.outline = console.outline_of(
                    self.project.tree, service.main_tree or self.project.main_tree
                )
        self.children.append(child)
        self.run.save()
        self.out.note(f"Started {service.role} {service.name} (pid {process.pid})")
        return child

    def _pump(self, name: str, stream: IO[bytes] | None, log_path: Path) -> None:
        if stream is None:
            return
        with log_path.open("ab") as log:
            for raw in iter(stream.readline, b""):
                log.write(raw)
                log.flush()
                self.out.log(name, raw.decode("utf-8", errors="replace"))

    # Watching.
    def is_ready(self, child: Child) -> bool:
        if child.service.transient and child.process.poll() == 0:
            return True
        return (self.plugins / child.service.name / "ready").exists()

    def unexpected_exit(self) -> Child | None:
        """A driver or skillset that exited when it should not have (transient drivers may exit 0)."""
        for child in self.children:
            code = child.process.poll()
            if (
                code is None
                or child.service.role == "executor"
                or child.record.state in ("exited", "stopped")
            ):
                continue
            if child.service.transient and code == 0:
                child.record.state, child.record.exit_code = "exited", 0
                self.out.note(f"Driver {child.service.name} finished (transient, exit 0)")
                self.run.save()
                continue
            child.record.state, child.record.exit_code = "failed", code
            return child
        return None

    def refresh_views(self) -> None:
        for child in self.children:
            if child.status is None:
                continue
            records = child.status.read()
            for record in records:
                child.view.apply(record)
                if record.get("event") == "error":
                    self.out.note(f"Executor {child.service.name} reported: {record.get('message')}")
            if records:
                self.out.show(child.view)

    def wait_ready(self, group: list[Child], role: str) -> int | None:
        """None once every child of `group` is ready; an exit code when the run must end."""
        timeout = {c.service.name: c.service.ready_timeout_s or self.project.ready_timeout_s for c in group}
        pending = list(group)
        while pending:
            if self.stopping.is_set():
                return 128 + (self.stop_signal or signal.SIGINT)
            failed = self.unexpected_exit()
            if failed is not None:
                return self._report_failure(failed)
            for child in list(pending):
                if self.is_ready(child):
                    pending.remove(child)
                    if child.record.state == "starting":
                        child.record.state = "ready"
                    self.out.note(
                        f"{role.capitalize()} {child.service.name} is ready "
                        f"({time.monotonic() - child.started_at:.1f} s)"
                    )
                    self.run.save()
                elif time.monotonic() - child.started_at > timeout[child.service.name]:
                    message = (
                        f"{role} {child.service.name} not ready after {timeout[child.service.name]:g} s "
                        f"(no {self.plugins / child.service.name / 'ready'})"
                    )
                    if self.project.on_timeout == "proceed":
                        self.out.note(message + "; proceeding (on_timeout: proceed)")
                        pending.remove(child)
                    else:
                        self.out.note(message)
                        self.run.message = message
                        return EXIT_NOT_READY
            self.stopping.wait(POLL_S)
        return None

    def _report_failure(self, child: Child) -> int:
        message = (
            f"{child.service.role.capitalize()} {child.service.name} exited unexpectedly with code "
            f"{child.record.exit_code}; stopping the run (log: {child.record.log})"
        )
        self.out.note(message)
        self.run.message = message
        self.run.save()
        return EXIT_COMPONENT_FAILED

    def wait_executors(self, executors: list[Child]) -> int:
        while True:
            self.refresh_views()
            if self.stopping.is_set():
                return 128 + (self.stop_signal or signal.SIGINT)
            failed = self.unexpected_exit()
            if failed is not None:
                return self._report_failure(failed)
            if all(c.process.poll() is not None for c in executors):
                for child in executors:
                    child.pump.join(timeout=2.0)
                self.refresh_views()
                codes = [c.process.returncode for c in executors]
                for child, code in zip(executors, codes, strict=True):
                    child.record.state, child.record.exit_code = "exited", code
                    result = child.view.finished.get("root_status") if child.view.finished else "unknown"
                    self.out.note(f"Executor {child.service.name} finished: tree {result}, exit code {code}")
                return next((code for code in codes if code != 0), 0)
            self.stopping.wait(WATCH_S)

    # Stopping.
    def stop_all(self) -> None:
        """Stops every running child in reverse start order: executors, skillsets, then drivers."""
        self.run.state = "stopping"
        self.run.save()
        for child in reversed(self.children):
            if child.process.poll() is None:
                self.out.note(f"Stopping {child.service.role} {child.service.name}")
                stop_process_group(child.process, STOP_GRACE_S)
                if child.record.state not in ("failed",):
                    child.record.state = "stopped"
                child.record.exit_code = child.process.returncode
            child.pump.join(timeout=2.0)
        self.refresh_views()

    def supervise(self) -> int:
        self.plugins.mkdir(parents=True, exist_ok=True)
        self.output_dir.mkdir(parents=True, exist_ok=True)
        code: int | None = None
        try:
            for role in ("driver", "skillset"):
                group = [self.start(s) for s in self.project.by_role(role)]
                code = self.wait_ready(group, role)
                if code is not None:
                    return code
                if self.stopping.is_set():
                    return 128 + (self.stop_signal or signal.SIGINT)
            executors = [self.start(s) for s in self.project.by_role("executor")]
            self.run.state = "running"
            self.run.save()
            code = self.wait_executors(executors) if executors else self._wait_for_signal()
            return code
        except components.ComponentNotFound as err:
            self.out.note(str(err))
            self.run.message = str(err)
            return EXIT_BAD_INPUT
        finally:
            self.stop_all()
            self.out.close_footer()

    def draw_trees(self, target: Path) -> list[Path]:
        """Draws each executor's tree with every node's last status; one executor gets `target`,
        several get `<stem>-<executor>.png` beside it."""
        from coral import tree_picture

        executors = [c for c in self.children if c.service.role == "executor" and c.view.outline]
        drawn = []
        for child in executors:
            path = (
                target if len(executors) == 1 else target.with_name(f"{target.stem}-{child.service.name}.png")
            )
            title = (
                f"{self.project.name} / {child.service.name}: tree {child.view.root} "
                f"after {child.view.ticks} ticks"
            )
            drawn.append(tree_picture.draw_tree(child.view.outline, child.view.last_statuses(), path, title))
        return drawn

    def _wait_for_signal(self) -> int:
        """No executor: keep the components up until a signal or an unexpected exit."""
        while not self.stopping.is_set():
            failed = self.unexpected_exit()
            if failed is not None:
                return self._report_failure(failed)
            self.stopping.wait(POLL_S)
        return 128 + (self.stop_signal or signal.SIGINT)


def stop_process_group(process: subprocess.Popen[Any], grace_s: float) -> None:
    """SIGINT the child's process group (components shut down cleanly on it), SIGKILL after `grace_s`.

    os.killpg, not psutil: psutil signals processes one by one, and the group also holds what the
    component started and lost track of."""
    try:
        os.killpg(process.pid, signal.SIGINT)
    except ProcessLookupError:
        pass
    try:
        process.wait(timeout=grace_s)
    except subprocess.TimeoutExpired:
        try:
            os.killpg(process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        process.wait(timeout=grace_s)
    # Grandchildren the component left behind in its group go too.
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
