"""matplotlib figures for the pictures Coral writes (SLAM map, behavior tree, benchmark plots).

One place sets the Agg backend (no display needed, safe in threads and CI) and writes PNGs aside
then renames them, so a reader never opens a half-written picture.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

DPI = 100


def new_figure(width_in: float, height_in: float) -> Any:
    """A matplotlib Figure of that size at DPI, laid out with constrained layout."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    return Figure(figsize=(width_in, height_in), dpi=DPI, layout="constrained")


def save_png(figure: Any, target: Path) -> Path:
    """Writes `figure` to `target` (creating its folder) atomically; returns `target`."""
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = target.with_name(f".{target.name}.tmp.png")
    figure.savefig(staging, dpi=DPI)
    staging.replace(target)
    return target
