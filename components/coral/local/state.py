"""The per-user runtime folder: one record per `coral run` instance, for `coral ps/stop/logs`.

Layout (root: $CORAL_STATE_DIR, else $XDG_STATE_HOME/coral, else ~/.local/state/coral):

    runs/<handle>/run.json          RunRecord: handle, group, project, supervisor pid, components
    runs/<handle>/<service>.log     everything the component printed (stdout and stderr)
    runs/<handle>/plugins/          the run's plugin location (what skillsets export)
    runs/<handle>/status-<executor>.jsonl   the executor's status records

The supervisor (`coral.local.supervising`) is the only writer of run.json; writes are atomic.
"""

from __future__ import annotations

import json
import os
import re
import secrets
import signal
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import psutil


def state_root() -> Path:
    explicit = os.environ.get("CORAL_STATE_DIR")
    if explicit:
        return Path(explicit)
    base = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(base) / "coral"


def runs_root() -> Path:
    return state_root() / "runs"


# A handle is a folder name under the runs folder, never a path.
HANDLE_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


def new_handle(project: str) -> str:
    return f"{project}-{secrets.token_hex(3)}"


@dataclass
class ComponentRecord:
    name: str
    role: str
    state: str = "pending"  # pending | starting | ready | exited | stopped | failed
    pid: int | None = None
    exit_code: int | None = None
    log: str = ""
    command: list[str] = field(default_factory=list)


@dataclass
class RunRecord:
    handle: str
    group: str
    project: str
    compose: str
    supervisor_pid: int
    started_at: float
    state: str = "starting"  # starting | running | stopping | finished
    exit_code: int | None = None
    message: str = ""
    output: str = ""
    components: list[ComponentRecord] = field(default_factory=list)

    @property
    def folder(self) -> Path:
        return runs_root() / self.handle

    def component(self, name: str) -> ComponentRecord:
        return next(c for c in self.components if c.name == name)

    def save(self) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        staging = self.folder / ".run.json.tmp"
        staging.write_text(json.dumps(asdict(self), indent=2) + "\n")
        staging.replace(self.folder / "run.json")

    @classmethod
    def from_dict(cls, raw: dict[str, Any]) -> RunRecord:
        components = [ComponentRecord(**c) for c in raw.pop("components", [])]
        return cls(**raw, components=components)


def pid_alive(pid: int | None) -> bool:
    """True while `pid` is a process that is not a zombie (psutil reads its state)."""
    if not pid:
        return False
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False
    except psutil.AccessDenied:
        return True


def load_runs() -> list[RunRecord]:
    """Every recorded run, oldest first; a run whose supervisor died reads as finished."""
    runs: list[RunRecord] = []
    root = runs_root()
    if not root.is_dir():
        return runs
    for path in sorted(root.glob("*/run.json"), key=lambda p: p.stat().st_mtime):
        try:
            record = RunRecord.from_dict(json.loads(path.read_text()))
        except (ValueError, TypeError, OSError):
            continue
        if record.state != "finished" and not pid_alive(record.supervisor_pid):
            record.state, record.message = "finished", record.message or "supervisor is gone"
        runs.append(record)
    return runs


def select_runs(
    runs: list[RunRecord], *, handle: str | None, group: str | None, everything: bool
) -> list[RunRecord]:
    if everything:
        return runs
    return [r for r in runs if (handle and r.handle == handle) or (group and r.group == group)]


def orphaned_components(run: RunRecord) -> list[ComponentRecord]:
    """Components still alive although their run's supervisor died without stopping them.

    A pid counts only while it still runs the recorded command line, so a pid the system has
    since given to another process is never touched.
    """
    if pid_alive(run.supervisor_pid) or run.exit_code is not None:
        return []
    return [c for c in run.components if c.pid and pid_alive(c.pid) and _runs_command(c.pid, c.command)]


def _runs_command(pid: int, command: list[str]) -> bool:
    try:
        return psutil.Process(pid).cmdline() == command
    except psutil.Error:
        return False


def kill_group(pid: int | None) -> None:
    """SIGKILLs the process group a component leads (each component leads its own process group).

    Stays on os.killpg: psutil signals single processes, and the group also holds whatever the
    component started that psutil's children() would miss once reparented."""
    if not pid:
        return
    try:
        os.killpg(pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
