"""The SLAM engine under the skillset's threads: readers of the pose never wait for a registration.

The skillset's worker registers scans while behaviors ask for the pose and the displacement on
other threads; KISS-ICP holds its lock (and the GIL) for a whole registration, so the readers must
not need that lock, and the trajectory must stay in registration order.
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
from coral.lidar import trajectory
from coral_skillsets.slam.core import SlamCore
from test_slam_sanitising import SHORT_BAG_ATE_BOUND_M, _scans


def test_pose_and_displacement_answer_while_a_registration_holds_the_odometry() -> None:
    core = SlamCore()
    core.process(np.random.default_rng(2).uniform(-10, 10, (3000, 3)), None, 1)
    answers: list[tuple[float, float]] = []
    # Held for the whole of a registration by the worker: a reader that needed it would block here.
    with core._odometry_lock:
        reader = threading.Thread(target=lambda: answers.append(core.displacement()), daemon=True)
        reader.start()
        reader.join(timeout=30)
        assert not reader.is_alive(), "displacement() waited for the registration in progress"
        assert np.isfinite(core.pose).all() and core.scans_processed == 1
    assert len(answers) == 1


def test_a_worker_thread_maps_the_bag_while_readers_poll_the_pose(short_dataset: Path) -> None:
    scans = _scans(short_dataset)
    core = SlamCore()
    done = threading.Event()
    seen: list[int] = []

    def register_all() -> None:
        for points, times, stamp in scans:
            core.process(points, times, stamp)
        done.set()

    worker = threading.Thread(target=register_all, daemon=True)
    worker.start()
    while not done.is_set():
        linear, angular = core.displacement()
        assert np.isfinite([linear, angular]).all()
        seen.append(core.scans_processed)
        done.wait(0.001)
    worker.join(timeout=60)
    assert seen == sorted(seen) and core.scans_processed == len(scans)
    stamps, estimate = core.trajectory()
    assert list(stamps) == [stamp for _, _, stamp in scans]
    true_stamps, truth = trajectory.read_poses_csv(short_dataset / "ground_truth.csv")
    error = trajectory.trajectory_error(*trajectory.match_by_stamp(stamps, estimate, true_stamps, truth))
    assert error.ate_rmse_m < SHORT_BAG_ATE_BOUND_M
