"""A copy of the SLAM example to spoil, for the tests of `coral validate`, `coral run` and
`coral convert` on projects a user got wrong."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "lidar-slam"


@pytest.fixture
def project(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("CORAL_BAG", str(tmp_path / "bag"))
    target = tmp_path / "lidar-slam"
    shutil.copytree(EXAMPLE, target)
    return target
