"""The LiDAR SLAM demo: generate (or reuse) the synthetic bag, `coral run` the example, score the result.

`run_demo` is what `coral slam-demo` (and `make demo-local`) calls. The bag is cached under
~/.cache/coral-on-kubernetes/bags/; the map and trajectory land in the output folder
(default ./out/lidar-slam/: slam_map.ply and slam_map.trajectory.csv). `evaluate` compares the
trajectory the SLAM skillset saved with the bag's ground truth (ATE after rigid alignment) and
draws both over the map into slam_map.png beside it; `coral demo` calls it on the robot's files.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from coral_core import terminal

from coral.lidar import generating, mapfile, picture, trajectory

EXAMPLE_MAP_NAME = "slam_map.ply"


@dataclass(frozen=True)
class Evaluation:
    """What the SLAM mission left in its output folder, scored against the bag's ground truth."""

    scans: int
    ground_truth_scans: int
    error: trajectory.TrajectoryError | None
    map_path: Path
    map_points: int
    picture_path: Path | None

    def summary(self) -> list[str]:
        """The lines both demos print under the mission's result."""
        lines = [
            f"Scans processed   : {self.scans} of {self.ground_truth_scans}",
            f"Map               : {self.map_path} ({self.map_points} points)",
        ]
        if self.error is not None:
            lines.append(
                f"Trajectory error  : ATE {self.error.ate_rmse_m:.3f} m RMSE, "
                f"RPE {self.error.rpe_rmse_m:.3f} m per scan"
            )
        else:
            lines.append("Trajectory error  : not available (no trajectory saved)")
        if self.picture_path is not None:
            lines.append(f"Picture           : {self.picture_path}")
        return lines


@dataclass(frozen=True)
class DemoResult:
    exit_code: int
    evaluation: Evaluation
    duration_s: float


def evaluate(output_dir: Path, dataset: Path, *, draw: bool = True) -> Evaluation:
    """Scores the map and trajectory in `output_dir` against `dataset`; with `draw`, writes the PNG.

    The picture is drawn whenever there is a map or a trajectory to show; its title carries the ATE.
    """
    map_path = output_dir / EXAMPLE_MAP_NAME
    estimate_file = map_path.with_suffix(".trajectory.csv")
    true_stamps, truth = trajectory.read_poses_csv(dataset / "ground_truth.csv")
    stamps, estimate = (
        trajectory.read_poses_csv(estimate_file)
        if estimate_file.is_file()
        else (np.empty(0, dtype=np.int64), np.empty((0, 4, 4)))
    )
    matched_est, matched_true = trajectory.match_by_stamp(stamps, estimate, true_stamps, truth)
    error = trajectory.trajectory_error(matched_est, matched_true) if len(matched_est) >= 2 else None
    points = mapfile.read_ply(map_path) if map_path.is_file() else np.empty((0, 3))
    drawn: Path | None = None
    if draw and (len(points) or len(estimate)):
        ate = f"ATE {error.ate_rmse_m:.3f} m RMSE" if error is not None else "no ATE (too few poses)"
        drawn = picture.draw_mission(
            map_path.with_suffix(".png"),
            points,
            estimate[:, :2, 3],
            truth[:, :2, 3],
            f"SLAM map, top-down: {len(points)} points, {len(stamps)} of {len(truth)} scans, {ate}",
        )
    return Evaluation(
        scans=len(stamps),
        ground_truth_scans=len(truth),
        error=error,
        map_path=map_path,
        map_points=len(points),
        picture_path=drawn,
    )


def run_demo(
    example: Path,
    params: generating.BagParams,
    *,
    output_dir: Path,
    live: bool | None = None,
    cache_root: Path | None = None,
    echo: Callable[[str], object] = print,
    tree_png: Path | None = None,
) -> DemoResult:
    from coral.local import running

    started = time.monotonic()
    echo(
        f"Synthetic LiDAR bag: seed {params.seed}, {params.scans} scans, {params.beams} beams"
        " (cached after the first run)"
    )
    with terminal.progress("Generating the bag") as step:
        dataset = generating.cached_dataset(params, cache_root, step)
    echo(f"Bag ready in {time.monotonic() - started:.1f} s: {dataset / 'bag'}")
    stem = output_dir / EXAMPLE_MAP_NAME
    for stale in (stem, stem.with_suffix(".trajectory.csv"), stem.with_suffix(".png")):
        stale.unlink(missing_ok=True)
    code = running.run_project(
        example,
        output_dir=output_dir,
        live=live,
        extra_env={"CORAL_BAG": str(dataset / "bag")},
        tree_png=tree_png,
    )
    return DemoResult(
        exit_code=code,
        evaluation=evaluate(output_dir, dataset),
        duration_s=time.monotonic() - started,
    )
