"""CPU seconds (user + system) of every process a benchmark starts, by process and by thread.

A `CpuSampler` reads /proc for the descendants of the benchmark's own process on a background
thread and keeps, for each process and each thread, the last CPU time it saw (a process that exits
loses at most one sampling period of CPU, its tail of shutdown). Processes are named by their
`--name` argument when they have one (Coral's components do), else by their command. CPU seconds
barely depend on how loaded the machine is, unlike wall time, so a slow run's table still says
where the work went. Linux only; elsewhere the tables stay empty.
"""

from __future__ import annotations

import os
import threading
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

PROC = Path("/proc")
TICKS_PER_S = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def _stat_fields(path: Path) -> list[str] | None:
    """Fields of a /proc stat file after the command name (which may hold spaces or parentheses)."""
    try:
        text = path.read_text()
    except OSError:
        return None
    return text[text.rfind(")") + 2 :].split()


def _cpu_s(fields: list[str]) -> float:
    # utime and stime are fields 14 and 15 of stat(5); `fields` starts at field 3.
    return (int(fields[11]) + int(fields[12])) / TICKS_PER_S


def _label(pid: int) -> str:
    try:
        argv = (PROC / str(pid) / "cmdline").read_bytes().split(b"\0")
    except OSError:
        return str(pid)
    args = [a.decode(errors="replace") for a in argv if a]
    if "--name" in args[:-1]:
        return args[args.index("--name") + 1]
    modules = [args[i + 1] for i, a in enumerate(args[:-1]) if a == "-m"]
    if modules:
        return modules[0]
    return Path(args[0]).name if args else str(pid)


def _thread_group(name: str) -> str:
    """Threads named `pool-3`, `pool-4` ... count as one group `pool-N`."""
    stripped = name.rstrip("0123456789")
    return f"{stripped}N" if stripped != name and stripped else name


@dataclass
class ProcessCpu:
    label: str
    cpu_s: float = 0.0
    threads: dict[int, tuple[str, float]] = field(default_factory=dict)
    # (monotonic time, CPU seconds) at each sample, for the CPU spent within a time window.
    history: list[tuple[float, float]] = field(default_factory=list)

    def cpu_between(self, start: float, end: float) -> float:
        """CPU seconds spent between two monotonic times, interpolated between samples."""
        return self._at(end) - self._at(start)

    def _at(self, moment: float) -> float:
        if not self.history or moment <= self.history[0][0]:
            return self.history[0][1] if self.history else 0.0
        for (t0, c0), (t1, c1) in zip(self.history, self.history[1:], strict=False):
            if moment <= t1:
                return c0 + (c1 - c0) * (moment - t0) / (t1 - t0) if t1 > t0 else c1
        return self.history[-1][1]

    def by_thread_group(self) -> dict[str, float]:
        groups: dict[str, float] = defaultdict(float)
        for name, seconds in self.threads.values():
            groups[_thread_group(name)] += seconds
        return dict(groups)


class CpuSampler:
    """Samples the CPU time of every descendant of `root_pid` (default: this process)."""

    def __init__(
        self,
        root_pid: int | None = None,
        period_s: float = 0.05,
        threads: bool = True,
        rescan_s: float = 0.25,
        root_label: str | None = None,
    ) -> None:
        """`root_label`: also sample the root process itself (in the benchmark, it runs `coral
        run`'s supervisor and this sampler), under that name."""
        self.root_pid = root_pid or os.getpid()
        self.root_label = root_label
        self.period_s = period_s
        self.rescan_s = rescan_s
        self._known: list[int] = []
        self._scanned_at = -1e9
        self.with_threads = threads
        self.processes: dict[int, ProcessCpu] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="cpu-sampler", daemon=True)

    def __enter__(self) -> CpuSampler:
        self._thread.start()
        return self

    def __exit__(self, *_exc: object) -> None:
        self._stop.set()
        self._thread.join()

    def _descendants(self) -> list[int]:
        parents: dict[int, int] = {}
        for entry in PROC.iterdir():
            if entry.name.isdigit():
                fields = _stat_fields(entry / "stat")
                if fields is not None:
                    parents[int(entry.name)] = int(fields[1])
        found = [self.root_pid] if self.root_label else []
        frontier = [self.root_pid]
        while frontier:
            parent = frontier.pop()
            children = [pid for pid, ppid in parents.items() if ppid == parent]
            found += children
            frontier += children
        return found

    def sample(self, rescan: bool = False) -> None:
        now = time.monotonic()
        if rescan or now - self._scanned_at >= self.rescan_s:
            self._known, self._scanned_at = self._descendants(), now
        for pid in self._known:
            fields = _stat_fields(PROC / str(pid) / "stat")
            if fields is None:
                continue
            record = self.processes.get(pid)
            if record is None:
                label = self.root_label if pid == self.root_pid and self.root_label else _label(pid)
                record = self.processes[pid] = ProcessCpu(label)
            record.cpu_s = max(record.cpu_s, _cpu_s(fields))
            record.history.append((now, record.cpu_s))
            if not self.with_threads:
                continue
            try:
                tasks = list((PROC / str(pid) / "task").iterdir())
            except OSError:
                continue
            for task in tasks:
                task_fields = _stat_fields(task / "stat")
                if task_fields is None:
                    continue
                try:
                    name = (task / "comm").read_text().strip()
                except OSError:
                    continue
                record.threads[int(task.name)] = (name, _cpu_s(task_fields))

    def _run(self) -> None:
        while not self._stop.is_set():
            self.sample()
            self._stop.wait(self.period_s)
        self.sample(rescan=True)

    def by_label(self, window: tuple[float, float] | None = None) -> dict[str, ProcessCpu]:
        """Processes with the same label added up; with `window` (monotonic start, end), only the
        CPU spent within it (threads are then left out: they are sampled as totals)."""
        merged: dict[str, ProcessCpu] = {}
        for record in self.processes.values():
            total = merged.setdefault(record.label, ProcessCpu(record.label))
            if window is not None:
                total.cpu_s += record.cpu_between(*window)
                continue
            total.cpu_s += record.cpu_s
            offset = len(total.threads)
            for index, thread in enumerate(record.threads.values()):
                total.threads[offset + index] = thread
        return merged


def table(title: str, processes: dict[str, ProcessCpu], *, threads: bool = False) -> list[str]:
    """Lines of a CPU table: one row per process (largest first), its busiest thread groups below."""
    lines = [f"{title}: CPU seconds (user+system) by process"]
    total = sum(p.cpu_s for p in processes.values())
    for record in sorted(processes.values(), key=lambda p: -p.cpu_s):
        share = record.cpu_s / total * 100 if total else 0.0
        lines.append(f"  {record.label:<28} {record.cpu_s:7.2f} s  {share:5.1f} %")
        if threads:
            groups = sorted(record.by_thread_group().items(), key=lambda kv: -kv[1])
            for name, seconds in groups:
                if seconds >= 0.05:
                    lines.append(f"      {name:<24} {seconds:7.2f} s")
    lines.append(f"  {'total':<28} {total:7.2f} s")
    return lines
