"""A memory cgroup (v1) for one process, as a pod's memory limit puts its container in one.

Used by the operator's hostile-input and load tests: the operator runs under the chart's limit,
counted and enforced by the kernel as in a pod (page cache of the files it reads included), and
the test reads the peak, the current usage and whether the kernel's OOM killer struck. The group
is made inside the test process's own memory cgroup, so whatever limit already applies to the
tests still applies. Needs root and a cgroup v1 memory hierarchy (`available` says whether).
"""

from __future__ import annotations

import os
import signal
import uuid
from pathlib import Path

from coral_testbed.waiting import wait_for

MEMORY_ROOT = Path("/sys/fs/cgroup/memory")


def available() -> str | None:
    """Why a memory cgroup cannot be made here, or None when it can."""
    if os.geteuid() != 0:
        return "memory cgroups need root"
    if not (MEMORY_ROOT / "memory.limit_in_bytes").exists():
        return f"no cgroup v1 memory hierarchy at {MEMORY_ROOT}"
    return None


def _own_group() -> Path:
    for line in Path("/proc/self/cgroup").read_text().splitlines():
        _, controllers, path = line.split(":", 2)
        if "memory" in controllers.split(","):
            return MEMORY_ROOT / path.lstrip("/")
    return MEMORY_ROOT


class MemoryCgroup:
    """A new memory cgroup limited to `limit_bytes` (swap included, where swap accounting exists)."""

    def __init__(self, limit_bytes: int, prefix: str = "coral-test") -> None:
        self.limit_bytes = limit_bytes
        self.path = _own_group() / f"{prefix}-{uuid.uuid4().hex[:8]}"
        self.path.mkdir()
        (self.path / "memory.limit_in_bytes").write_text(str(limit_bytes))
        swap = self.path / "memory.memsw.limit_in_bytes"
        if swap.exists():
            swap.write_text(str(limit_bytes))

    def join(self) -> None:
        """Moves the calling process in (call from a child before it execs: `preexec_fn`)."""
        (self.path / "cgroup.procs").write_text(str(os.getpid()))

    def _read(self, name: str) -> str:
        return (self.path / name).read_text()

    def usage_bytes(self) -> int:
        return int(self._read("memory.usage_in_bytes"))

    def peak_bytes(self) -> int:
        return int(self._read("memory.max_usage_in_bytes"))

    def rss_bytes(self) -> int:
        """Anonymous memory of the group's processes (the heap), without the page cache."""
        stat = dict(line.split() for line in self._read("memory.stat").splitlines())
        return int(stat.get("total_rss", stat.get("rss", "0")))

    def oom_kills(self) -> int:
        """Processes of the group the kernel's OOM killer ended (0 on kernels that do not count)."""
        control = dict(line.split() for line in self._read("memory.oom_control").splitlines())
        return int(control.get("oom_kill", "0"))

    def failures(self) -> int:
        """How often an allocation hit the limit (the kernel then reclaimed or killed)."""
        return int(self._read("memory.failcnt"))

    def pids(self) -> set[int]:
        return {int(pid) for pid in self._read("cgroup.procs").split()}

    def remove(self, timeout: float = 15.0) -> None:
        """Kills what is left in the group and removes it.

        Raises:
            WaitTimeout: processes were still in the group after `timeout` seconds.
        """

        def none_left() -> bool:
            # A process forking while it is killed leaves a child behind: each pass kills what is left.
            left = self.pids()
            for pid in left:
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            return not left

        wait_for(
            none_left,
            timeout=timeout,
            interval=0.1,
            message=lambda: f"processes {sorted(self.pids())} in {self.path} to die of SIGKILL",
        )
        os.rmdir(self.path)
