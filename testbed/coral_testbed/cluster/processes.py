"""Starting and stopping the control plane's processes, each in its own process group.

Used by `controlplane` (start, stop, status). A process is recorded by pid plus its kernel start
time (read by psutil), so a later `down` never signals an unrelated process that reused the pid.
"""

from __future__ import annotations

import ctypes
import os
import signal
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import psutil

from coral_testbed.waiting import WaitTimeout, wait_for

_PR_SET_PDEATHSIG = 1


@dataclass(frozen=True)
class Recorded:
    """A started component: enough to find, check and stop it again from another process."""

    name: str
    pid: int
    start_time: str
    log: Path

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "pid": self.pid, "start_time": self.start_time, "log": str(self.log)}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Recorded:
        return cls(data["name"], int(data["pid"]), str(data["start_time"]), Path(data["log"]))


def process_start_time(pid: int) -> str | None:
    """When the kernel started `pid` (psutil's create_time), None if it is gone or a zombie."""
    try:
        found = psutil.Process(pid)
        if found.status() == psutil.STATUS_ZOMBIE:
            return None
        return f"{found.create_time():.2f}"
    except psutil.NoSuchProcess:
        return None


def is_alive(process: Recorded) -> bool:
    return process_start_time(process.pid) == process.start_time


def die_with_parent() -> None:
    """A `preexec_fn`: the kernel SIGTERMs the child when the process that started it dies.

    For test sessions only, so a killed pytest never leaves a control plane or an operator behind.
    """
    libc = ctypes.CDLL("libc.so.6", use_errno=True)
    libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)


# `spawn`'s flag of the same name shadows the function inside it.
_ask_for_sigterm_on_parent_death = die_with_parent


def spawn(
    name: str,
    argv: list[str],
    log: Path,
    env: dict[str, str] | None = None,
    die_with_parent: bool = False,
) -> Recorded:
    """Starts `argv` in a new session with stdout and stderr appended to `log`."""
    log.parent.mkdir(parents=True, exist_ok=True)
    with log.open("ab") as sink:
        child = subprocess.Popen(
            argv,
            stdin=subprocess.DEVNULL,
            stdout=sink,
            stderr=subprocess.STDOUT,
            env=env,
            start_new_session=True,
            preexec_fn=_ask_for_sigterm_on_parent_death if die_with_parent else None,
        )
    start_time = process_start_time(child.pid)
    # A child that already exited still has a start time until reaped; if not, it died instantly.
    return Recorded(name, child.pid, start_time or "gone", log)


def _reap(pid: int) -> None:
    # Children of this Python process must be waited for, or they linger as zombies.
    try:
        os.waitpid(pid, os.WNOHANG)
    except ChildProcessError:
        pass


def stop(process: Recorded, timeout: float = 15.0) -> None:
    """SIGTERMs the process group, SIGKILLs it after `timeout`, returns once the process is gone."""
    if not is_alive(process):
        _reap(process.pid)
        return

    def gone() -> bool:
        _reap(process.pid)
        return not is_alive(process)

    for sig, grace in ((signal.SIGTERM, timeout), (signal.SIGKILL, 5.0)):
        try:
            os.killpg(process.pid, sig)
        except ProcessLookupError:
            pass
        try:
            wait_for(gone, timeout=grace, interval=0.05, message=f"{process.name} to exit")
            return
        except WaitTimeout:
            continue
    raise RuntimeError(f"{process.name} (pid {process.pid}) survived SIGKILL")


def log_tail(path: Path, lines: int = 25) -> str:
    try:
        text = path.read_text(errors="replace")
    except OSError:
        return "(no log)"
    return "\n".join(text.splitlines()[-lines:])
