"""Process tests of `coral run`: a short synthetic bag and a private copy of the SLAM example per test."""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml
from coral.lidar.generating import BagParams, generate
from fixtures.processes import Spawn
from run_helpers import StartRun, coral

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "lidar-slam"
SHORT_BAG = BagParams(seed=11, scans=40)


@pytest.fixture(scope="session")
def short_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return generate(SHORT_BAG, tmp_path_factory.mktemp("bags") / "short")


@pytest.fixture
def example_copy(tmp_path: Path) -> Callable[..., Path]:
    """Copies the example into tmp_path, optionally changing the bag player's rate."""

    def make(rate: float | None = None) -> Path:
        target = tmp_path / "lidar-slam"
        shutil.copytree(EXAMPLE, target)
        if rate is not None:
            params = yaml.safe_load((target / "params.yaml").read_text())
            params["bag_player"]["ros__parameters"]["rate"] = rate
            (target / "params.yaml").write_text(yaml.safe_dump(params))
        return target

    return make


@pytest.fixture
def run_env(ros_env: dict[str, str], tmp_path: Path, short_bag: Path) -> dict[str, str]:
    """Environment for `coral run`: private ROS domain, private state folder, the short bag."""
    return {**ros_env, "CORAL_STATE_DIR": str(tmp_path / "state"), "CORAL_BAG": str(short_bag / "bag")}


@pytest.fixture
def start_run(spawned: Spawn, run_env: dict[str, str]) -> StartRun:
    """Starts `coral run EXAMPLE --output OUTPUT --no-live [EXTRA...]` in the test's environment,
    stdout and stderr together as text (read them with `communicate`)."""

    def start(example: Path, output: Path, *extra: str) -> subprocess.Popen[str]:
        return spawned(
            coral("run", str(example), "--output", str(output), "--no-live", *extra),
            env=run_env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )

    return start
