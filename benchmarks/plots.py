"""The benchmarks' figures as PNG plots (matplotlib, Agg), written when a benchmark runs with `--plot DIR`.

`fleet_times`: time to Ready and rolling-update time against robot count, Coral beside the
DaemonSet reference. `slam_throughput`: scans/s of each KISS-ICP/Coral pair with their ratio.
Each returns the path it wrote; the benchmark prints it as a `# plot:` line after its BENCH lines.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from coral import figures

SIZE_IN = (10.0, 4.5)


@dataclass(frozen=True)
class FleetPoint:
    robots: int
    coral_ready_s: float
    coral_update_s: float
    daemonset_ready_s: float
    daemonset_update_s: float


def _figure(columns: int) -> tuple[Any, list[Any]]:
    figure = figures.new_figure(*SIZE_IN)
    return figure, list(figure.subplots(1, columns, squeeze=False)[0])


def fleet_times(points: Sequence[FleetPoint], folder: Path) -> Path:
    """`fleet.png`: two panels (ready, rolling update), seconds against robots, Coral vs DaemonSet."""
    figure, (ready, update) = _figure(2)
    ordered = sorted(points, key=lambda p: p.robots)
    robots = [p.robots for p in ordered]
    panels = (
        (ready, "time to Ready", "coral_ready_s", "daemonset_ready_s"),
        (update, "rolling update (maxUnavailable 10%)", "coral_update_s", "daemonset_update_s"),
    )
    for axes, title, coral, reference in panels:
        axes.plot(robots, [getattr(p, coral) for p in ordered], "o-", color="tab:blue", label="Coral")
        axes.plot(
            robots,
            [getattr(p, reference) for p in ordered],
            "s--",
            color="tab:gray",
            label="three DaemonSets",
        )
        axes.set_title(title)
        axes.set_xlabel("robots")
        axes.set_ylabel("seconds")
        axes.set_ylim(bottom=0)
        axes.grid(True, linewidth=0.3)
        axes.legend()
    figure.suptitle("One CoralSystem against a DaemonSet on kwok robots")
    return figures.save_png(figure, folder / "fleet.png")


def slam_throughput(pairs: Sequence[tuple[float, float]], folder: Path) -> Path:
    """`slam_throughput.png`: (KISS-ICP, Coral) scans/s of each pair as bars, the ratio above."""
    figure, (axes,) = _figure(1)
    index = list(range(1, len(pairs) + 1))
    width = 0.38
    axes.bar([i - width / 2 for i in index], [k for k, _ in pairs], width, color="tab:gray", label="KISS-ICP")
    axes.bar([i + width / 2 for i in index], [c for _, c in pairs], width, color="tab:blue", label="Coral")
    for i, (kiss, coral) in zip(index, pairs, strict=True):
        axes.annotate(f"{coral / kiss:.2f}x", (i, max(kiss, coral)), ha="center", va="bottom", fontsize=9)
    axes.set_xticks(index, [f"pair {i}" for i in index])
    axes.set_ylabel("scans per second")
    axes.set_title("SLAM throughput per KISS-ICP/Coral pair (ratio Coral/KISS-ICP above)")
    axes.legend(loc="lower right")
    axes.grid(True, axis="y", linewidth=0.3)
    return figures.save_png(figure, folder / "slam_throughput.png")
