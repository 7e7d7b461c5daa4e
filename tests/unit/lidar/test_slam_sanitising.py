"""The SLAM skillset's engine: KISS-ICP fed only safe scans, a usable trajectory, map files.

KISS-ICP aborts the whole process through a C++ assertion (Sophus `SO3::exp failed`) when
deskewing runs on a scan whose point timestamps are all equal, and real LiDAR drivers emit NaN
points for missing returns (DESIGN section 9). The first test shows the abort is real (in a child
process); the others show the skillset's engine turns such scans into one handled result.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from coral.lidar import clouds, generating, trajectory
from coral_skillsets.slam.core import MapFileError, ScanRejected, SlamCore, read_ply, sanitise

# Measured on the 40-scan test bag (seed 11): 0.04 m; the bound leaves room for other platforms.
SHORT_BAG_ATE_BOUND_M = 0.25


def _scans(dataset: Path) -> list[tuple[np.ndarray, np.ndarray | None, int]]:
    from rosbags.highlevel import AnyReader

    out = []
    with AnyReader([dataset / "bag"]) as reader:
        connections = [c for c in reader.connections if c.topic == generating.POINTS_TOPIC]
        for connection, stamp, raw in reader.messages(connections=connections):
            m = reader.deserialize(raw, connection.msgtype)
            points, times = clouds.decode(m.fields, m.data, m.point_step, m.width, m.height)
            out.append((points, times, stamp))
    return out


def test_raw_kiss_icp_aborts_the_process_on_equal_point_times() -> None:
    script = textwrap.dedent("""
        import numpy as np
        from kiss_icp.config import KISSConfig
        from kiss_icp.kiss_icp import KissICP
        config = KISSConfig()
        config.mapping.voxel_size = 0.4
        odometry = KissICP(config)
        points = np.random.default_rng(0).uniform(-10, 10, (5000, 3))
        for step in range(3):
            odometry.register_frame(points + 0.1 * step, np.zeros(len(points)))
        print("survived")
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert result.returncode != 0 and "survived" not in result.stdout


def test_equal_point_times_disable_deskewing_for_that_scan_only() -> None:
    points = np.random.default_rng(0).uniform(-10, 10, (5000, 3))
    core = SlamCore()
    for step in range(3):
        result = core.process(points + 0.1 * step, np.zeros(len(points)), stamp_ns=step)
        assert not result.deskewed
    assert np.isfinite(core.pose).all() and core.scans_processed == 3
    assert core.process(points, np.linspace(0, 0.1, len(points)), stamp_ns=9).deskewed


def test_a_nan_laden_scan_costs_nothing_but_its_nan_points(short_dataset: Path) -> None:
    scans = _scans(short_dataset)
    core = SlamCore()
    for points, times, stamp in scans[:5]:
        core.process(points, times, stamp)
    points, times, stamp = scans[5]
    laden = points.copy()
    laden[::4] = np.nan
    laden[1::9, 2] = np.inf
    result = core.process(laden, times, stamp)
    assert result.dropped == np.count_nonzero(~np.isfinite(laden).all(axis=1))
    assert np.isfinite(result.pose).all()
    assert core.scans_processed == 6


def test_a_scan_without_usable_points_is_rejected_and_leaves_the_pose_alone() -> None:
    core = SlamCore()
    core.process(np.random.default_rng(1).uniform(-10, 10, (3000, 3)), None, 1)
    before = core.pose
    with pytest.raises(ScanRejected, match="0 usable points"):
        core.process(np.full((500, 3), np.nan), None, 2)
    with pytest.raises(ScanRejected, match="shape"):
        core.process(np.zeros((10, 2)), None, 3)
    assert np.array_equal(core.pose, before) and core.scans_processed == 1 and core.rejected == 1


def test_sanitise_keeps_times_aligned_with_the_points_it_keeps() -> None:
    points = np.arange(30, dtype=float).reshape(10, 3)
    times = np.linspace(0, 0.09, 10)
    points[3] = np.nan
    times[7] = np.nan
    clean = sanitise(points, times)
    assert len(clean.points) == len(clean.times) == 8 and clean.dropped == 2
    assert list(clean.times) == [t for i, t in enumerate(np.linspace(0, 0.09, 10)) if i not in (3, 7)]


def test_the_short_bag_is_mapped_with_a_small_trajectory_error(short_dataset: Path, tmp_path: Path) -> None:
    core = SlamCore()
    for points, times, stamp in _scans(short_dataset):
        core.process(points, times, stamp)
    stamps, estimate = core.trajectory()
    true_stamps, truth = trajectory.read_poses_csv(short_dataset / "ground_truth.csv")
    error = trajectory.trajectory_error(*trajectory.match_by_stamp(stamps, estimate, true_stamps, truth))
    assert error.pairs == 40
    assert error.ate_rmse_m < SHORT_BAG_ATE_BOUND_M

    saved = core.save_map(tmp_path / "maps" / "map.ply")
    assert saved > 1000 and len(read_ply(tmp_path / "maps" / "map.ply")) == saved
    assert len(trajectory.read_poses_csv(tmp_path / "maps" / "map.trajectory.csv")[0]) == 40

    relocalising = SlamCore()
    assert relocalising.load_map(tmp_path / "maps" / "map.ply") == saved
    assert len(relocalising.global_map()) > 0


def test_a_file_that_is_not_a_map_is_refused_with_its_name(tmp_path: Path) -> None:
    bad = tmp_path / "bad.ply"
    bad.write_text("not a ply")
    with pytest.raises(MapFileError, match=str(bad)):
        SlamCore().load_map(bad)
    with pytest.raises(MapFileError, match="cannot read"):
        SlamCore().load_map(tmp_path / "missing.ply")
