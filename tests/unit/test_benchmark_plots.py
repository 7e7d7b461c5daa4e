"""`--plot DIR` of the benchmarks: the fleet and SLAM figures as PNGs a person can read."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

from coral.figures import DPI
from fixtures.pictures import count_near, pixels

BLUE, GREY = (31, 119, 180), (127, 127, 127)  # matplotlib's tab:blue (Coral), tab:gray (reference)


def _plots() -> ModuleType:
    path = Path(__file__).resolve().parents[2] / "benchmarks" / "plots.py"
    spec = importlib.util.spec_from_file_location("bench_plots", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the class is built
    spec.loader.exec_module(module)
    return module


def test_the_fleet_plot_shows_coral_and_the_daemonset_against_robot_count(tmp_path: Path) -> None:
    plots = _plots()
    points = [plots.FleetPoint(n, n * 0.05, n * 0.08, n * 0.04, n * 0.05) for n in (1000, 100, 500)]
    drawn = plots.fleet_times(points, tmp_path / "figures")
    assert drawn == tmp_path / "figures" / "fleet.png"
    rgb = pixels(drawn, (int(plots.SIZE_IN[0] * DPI), int(plots.SIZE_IN[1] * DPI)), min_ink=0.02)
    assert count_near(rgb, BLUE, 30) > 300 and count_near(rgb, GREY, 10) > 200


def test_the_slam_plot_has_a_pair_of_bars_per_run(tmp_path: Path) -> None:
    plots = _plots()
    drawn = plots.slam_throughput([(120.0, 110.0), (118.0, 115.0), (121.0, 98.0)], tmp_path)
    assert drawn == tmp_path / "slam_throughput.png"
    rgb = pixels(drawn, (int(plots.SIZE_IN[0] * DPI), int(plots.SIZE_IN[1] * DPI)))
    assert count_near(rgb, BLUE, 10) > 5000 and count_near(rgb, GREY, 10) > 5000
