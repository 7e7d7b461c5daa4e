"""The SLAM mission as a picture: a top-down PNG of the map, the estimated and the true trajectory.

Drawn with matplotlib (`coral.figures`) by the demo report (`coral.lidar.demo`),
for `coral slam-demo` and `coral demo` alike. Estimate and map are in the SLAM frame, the ground
truth in the bag's; both start at the first scan's pose, so they overlay without alignment.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from coral import figures

SIZE_PX = (1000, 800)
MAX_MAP_POINTS = 60_000


def draw_mission(
    target: Path,
    map_points: np.ndarray,
    estimate_xy: np.ndarray,
    truth_xy: np.ndarray,
    title: str,
) -> Path:
    """Writes the PNG (SIZE_PX pixels) to `target`, aside then renamed; returns `target`."""
    figure = figures.new_figure(SIZE_PX[0] / figures.DPI, SIZE_PX[1] / figures.DPI)
    axes = figure.add_subplot()
    if len(map_points):
        # An even subsample keeps big maps quick to draw without changing what the eye sees.
        step = max(1, len(map_points) // MAX_MAP_POINTS)
        shown = map_points[::step]
        axes.scatter(
            shown[:, 0], shown[:, 1], s=0.3, c=shown[:, 2], cmap="Greys_r", alpha=0.6, label="map points"
        )
    if len(truth_xy):
        axes.plot(truth_xy[:, 0], truth_xy[:, 1], color="tab:green", linewidth=2.5, label="ground truth")
    if len(estimate_xy):
        axes.plot(
            estimate_xy[:, 0], estimate_xy[:, 1], color="tab:red", linewidth=1.2, label="estimated trajectory"
        )
        axes.plot(*estimate_xy[0], marker="o", color="tab:red")
    axes.set_aspect("equal", adjustable="datalim")
    axes.set_xlabel("x [m]")
    axes.set_ylabel("y [m]")
    axes.set_title(title)
    axes.legend(loc="upper right", markerscale=12)
    axes.grid(True, linewidth=0.3)
    return figures.save_png(figure, target)
