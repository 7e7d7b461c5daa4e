"""The LiDAR SLAM demo: generate (or reuse) the synthetic bag, `coral run` the example, score the result.

`run_demo` is what `coral slam-demo` (and `make demo`) calls. The bag is cached under
~/.cache/coral-on-kubernetes/bags/; the map and trajectory land in the output folder
(default ./out/lidar-slam/: slam_map.ply and slam_map.trajectory.csv). Scoring compares the
trajectory the SLAM skillset saved with the bag's ground truth (ATE after rigid alignment).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from coral.lidar import generating, trajectory

EXAMPLE_MAP_NAME = "slam_map.ply"


@dataclass(frozen=True)
class DemoResult:
    exit_code: int
    scans: int
    ground_truth_scans: int
    ate_m: float | None
    rpe_m: float | None
    map_path: Path
    map_points: int
    duration_s: float


def score(output_dir: Path, dataset: Path) -> tuple[int, int, trajectory.TrajectoryError | None, int]:
    """(scans in the saved trajectory, scans in the bag, error or None, points in the map file)."""
    map_path = output_dir / EXAMPLE_MAP_NAME
    estimate_file = map_path.with_suffix(".trajectory.csv")
    true_stamps, truth = trajectory.read_poses_csv(dataset / "ground_truth.csv")
    if not estimate_file.is_file():
        return 0, len(truth), None, 0
    stamps, estimate = trajectory.read_poses_csv(estimate_file)
    matched_est, matched_true = trajectory.match_by_stamp(stamps, estimate, true_stamps, truth)
    error = trajectory.trajectory_error(matched_est, matched_true) if len(matched_est) >= 2 else None
    points = 0
    if map_path.is_file():
        header = map_path.read_bytes()[:512].decode("ascii", errors="replace")
        points = next(
            (int(line.split()[-1]) for line in header.splitlines() if line.startswith("element vertex")), 0
        )
    return len(stamps), len(truth), error, points


def run_demo(
    example: Path,
    params: generating.BagParams,
    *,
    output_dir: Path,
    live: bool | None = None,
    cache_root: Path | None = None,
    echo: object = print,
) -> DemoResult:
    from coral.local import running

    started = time.monotonic()
    echo(
        f"Synthetic LiDAR bag: seed {params.seed}, {params.scans} scans, {params.beams} beams"
        " (cached after the first run)"
    )
    dataset = generating.cached_dataset(params, cache_root)
    echo(f"Bag ready in {time.monotonic() - started:.1f} s: {dataset / 'bag'}")
    for stale in (
        output_dir / EXAMPLE_MAP_NAME,
        output_dir / EXAMPLE_MAP_NAME.replace(".ply", ".trajectory.csv"),
    ):
        stale.unlink(missing_ok=True)
    code = running.run_project(
        example, output_dir=output_dir, live=live, extra_env={"CORAL_BAG": str(dataset / "bag")}
    )
    scans, total, error, points = score(output_dir, dataset)
    return DemoResult(
        exit_code=code,
        scans=scans,
        ground_truth_scans=total,
        ate_m=error.ate_rmse_m if error else None,
        rpe_m=error.rpe_rmse_m if error else None,
        map_path=output_dir / EXAMPLE_MAP_NAME,
        map_points=points,
        duration_s=time.monotonic() - started,
    )
