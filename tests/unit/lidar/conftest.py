"""A short synthetic bag shared by the LiDAR and SLAM unit tests (generated once per session)."""

from __future__ import annotations

from pathlib import Path

import pytest
from coral.lidar.generating import BagParams, generate

SHORT_BAG = BagParams(seed=11, scans=40)


@pytest.fixture(scope="session")
def short_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return generate(SHORT_BAG, tmp_path_factory.mktemp("lidar") / "dataset")
