"""`coral run` as a library: parse the project, record the run, supervise it, report the result.

Called by the `coral run` verb (`coral.local.cli`), the demo and the process tests.
`run_project` blocks until the run ends and returns its exit code; `start_detached` starts the
same thing as a background process and returns its handle at once (for `coral ps/stop/logs`).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from coral_core import compose, polling

from coral.local import console, state, supervising


@dataclass(frozen=True)
class Groot2Settings:
    """`coral run --groot2-port/--groot2-allow-hooks/--groot2-wait`, handed to every executor."""

    port: int | None = None
    allow_hooks: bool = False
    wait_s: float = 0.0

    def apply(self, project: compose.Project) -> None:
        project.groot2_port = self.port
        project.groot2_allow_hooks = self.allow_hooks
        project.groot2_wait_s = self.wait_s

    def arguments(self) -> list[str]:
        if self.port is None:
            return []
        argv = ["--groot2-port", str(self.port)]
        if self.allow_hooks:
            argv.append("--groot2-allow-hooks")
        if self.wait_s:
            argv += ["--groot2-wait", f"{self.wait_s:g}"]
        return argv


def default_output_dir(project: compose.Project) -> Path:
    return Path.cwd() / "out" / project.name


def load_project(target: Path, extra_env: dict[str, str] | None = None) -> compose.Project:
    """The parsed project; `extra_env` (e.g. `--env`) takes part in `${VAR}` interpolation."""
    environ = {**os.environ, **(extra_env or {})}
    return compose.parse_compose(compose.find_compose_file(Path(target)), environ)


def run_project(
    target: Path,
    *,
    handle: str | None = None,
    group: str | None = None,
    output_dir: Path | None = None,
    live: bool | None = None,
    extra_env: dict[str, str] | None = None,
    stream: object | None = None,
    tree_png: Path | None = None,
    groot2: Groot2Settings | None = None,
) -> int:
    """Runs the project in `target` (folder or compose file) in the foreground; returns the exit code."""
    out = console.Console(stream, live=live)  # type: ignore[arg-type]
    try:
        project = load_project(target, extra_env)
    except compose.ComposeError as err:
        out.note(f"error: {err}")
        return supervising.EXIT_BAD_INPUT
    if groot2 is not None:
        groot2.apply(project)
    handle = handle or state.new_handle(project.name)
    output = (output_dir or default_output_dir(project)).resolve()
    run = state.RunRecord(
        handle=handle,
        group=group or project.name,
        project=project.name,
        compose=str(project.file),
        supervisor_pid=os.getpid(),
        started_at=time.time(),
        output=str(output),
        components=[state.ComponentRecord(name=s.name, role=s.role) for s in project.services],
    )
    if (run.folder / "run.json").exists():
        out.note(f"error: a run with handle {handle} already exists ({run.folder})")
        return supervising.EXIT_BAD_INPUT
    run.save()
    for service in project.services:
        out.register(service.name)
    out.register("coral")
    out.note(
        f"Run {handle} (group {run.group}): {len(project.services)} component(s) from {project.file}; "
        f"output in {output}"
    )
    supervisor = supervising.Supervisor(project, run, out, output_dir=output, extra_env=extra_env)
    supervisor.install_signal_handlers()
    code = supervisor.supervise()
    run.state, run.exit_code = "finished", code
    run.save()
    if tree_png is not None:
        for picture in supervisor.draw_trees(tree_png.resolve()):
            out.note(f"Tree picture: {picture}")
    out.note(f"Run {handle} finished with exit code {code}")
    return code


def start_detached(
    target: Path,
    *,
    handle: str | None,
    group: str | None,
    output_dir: Path | None,
    tree_png: Path | None = None,
    wait_s: float = 15.0,
    groot2: Groot2Settings | None = None,
) -> str:
    """Starts `coral run` in the background (own session); returns its handle once it is recorded."""
    project = load_project(target)
    handle = handle or state.new_handle(project.name)
    argv = [sys.executable, "-m", "coral", "run", str(target), "--handle", handle, "--no-live"]
    if group:
        argv += ["--group", group]
    if output_dir:
        argv += ["--output", str(output_dir)]
    if tree_png:
        argv += ["--tree-png", str(tree_png.resolve())]
    if groot2 is not None:
        argv += groot2.arguments()
    folder = state.runs_root() / handle
    folder.mkdir(parents=True, exist_ok=True)
    with (folder / "supervisor.log").open("ab") as log:
        process = subprocess.Popen(
            argv, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True
        )

    def recorded() -> bool:
        if (folder / "run.json").exists():
            return True
        if process.poll() is not None:
            raise RuntimeError(
                f"coral run exited with code {process.returncode}; see {folder / 'supervisor.log'}"
            )
        return False

    if polling.poll_until(recorded, timeout_s=wait_s, interval_s=0.05):
        return handle
    raise RuntimeError(
        f"coral run did not record itself within {wait_s:g} s; see {folder / 'supervisor.log'}"
    )
