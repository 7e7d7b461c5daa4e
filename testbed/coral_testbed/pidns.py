"""A command as the first process of a new PID namespace, as a container's command runs: for
tests of how such a process takes signals (the kernel drops those it does not catch)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path


def can_make_one() -> bool:
    """Whether `unshare` is here and may make a PID namespace (root, or user namespaces allowed)."""
    unshare = shutil.which("unshare")
    return unshare is not None and subprocess.run([unshare, "--pid", "--fork", "true"]).returncode == 0


def first_process(argv: list[str], **popen: object) -> subprocess.Popen[str]:
    """Starts `argv` as the first process of a new PID namespace; the returned launcher's own
    process is `unshare`, which ends with it and kills it if it dies first."""
    return subprocess.Popen(["unshare", "--pid", "--fork", "--kill-child", *argv], **popen)  # type: ignore[call-overload]


def first_process_of(launcher: subprocess.Popen[str]) -> int | None:
    """The host PID of the namespace's first process, once `unshare` has forked it."""
    try:
        children = Path(f"/proc/{launcher.pid}/task/{launcher.pid}/children").read_text().split()
    except OSError:
        return None
    return int(children[0]) if children else None
