"""The `coral generate-bag` and `coral slam-demo` verbs (thin: options in, one library call)."""

from __future__ import annotations

import sys
from pathlib import Path

import click
from coral_core import terminal

from coral.lidar import generating
from coral.local.cli import TREE_PNG, output_option

DEFAULT_EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "lidar-slam"


# (option, type, help) of each BagParams field the verbs expose; defaults come from BagParams.
BAG_OPTIONS = (
    ("seed", int, "Scene and noise seed."),
    ("scans", click.IntRange(min=2), "Number of 10 Hz sweeps."),
    ("beams", click.IntRange(min=2, max=generating.MAX_BEAMS), "Lasers per column."),
    ("columns", click.IntRange(min=16, max=generating.MAX_COLUMNS), "Firing columns per sweep."),
    ("speed", click.FloatRange(min=0), "Metres per second."),
)


def bag_options(function: click.decorators.FC) -> click.decorators.FC:
    defaults = generating.BagParams()
    for name, kind, text in reversed(BAG_OPTIONS):
        option = click.option(
            f"--{name}", type=kind, default=getattr(defaults, name), show_default=True, help=text
        )
        function = option(function)
    return function


def _bag_params(seed: int, scans: int, beams: int, columns: int, speed: float) -> generating.BagParams:
    try:
        return generating.BagParams(seed=seed, scans=scans, beams=beams, columns=columns, speed=speed)
    except ValueError as err:
        raise click.UsageError(str(err)) from err


@click.command("generate-bag")
@bag_options
@output_option(None, "Dataset folder to create (default: the cache, ~/.cache/coral-on-kubernetes/bags/...).")
def generate_bag_command(
    seed: int, scans: int, beams: int, columns: int, speed: float, output_dir: Path | None
) -> None:
    """Write a synthetic LiDAR ROS 2 bag (PointCloud2 + ground truth) from a seed; print its folder."""
    params = _bag_params(seed=seed, scans=scans, beams=beams, columns=columns, speed=speed)
    try:
        with terminal.progress("Generating the bag", stream=sys.stderr) as step:
            folder = (
                generating.generate(params, output_dir, step)
                if output_dir
                else generating.cached_dataset(params, progress=step)
            )
    except (ValueError, OSError) as err:
        raise click.ClickException(str(err)) from err
    click.echo(folder)


@click.command("slam-demo")
@bag_options
@click.option(
    "--example",
    type=click.Path(exists=True, path_type=Path),
    default=DEFAULT_EXAMPLE,
    show_default=True,
    help="The example project to run.",
)
@output_option(Path("out/lidar-slam"), "Where the map, trajectory and picture go.")
@click.option("--live/--no-live", default=None, help="Live tree view (default: on a terminal).")
@TREE_PNG
def slam_demo_command(
    seed: int,
    scans: int,
    beams: int,
    columns: int,
    speed: float,
    example: Path,
    output_dir: Path,
    live: bool | None,
    tree_png: Path | None,
) -> None:
    """The LiDAR SLAM mission end to end: bag, `coral run`, map, trajectory error against ground truth."""
    from coral.lidar import demo

    params = _bag_params(seed=seed, scans=scans, beams=beams, columns=columns, speed=speed)
    result = demo.run_demo(
        example, params, output_dir=output_dir.resolve(), live=live, echo=click.echo, tree_png=tree_png
    )
    click.echo("")
    click.echo(
        f"Mission exit code : {result.exit_code} ({'SUCCESS' if result.exit_code == 0 else 'not SUCCESS'})"
    )
    for line in result.evaluation.summary():
        click.echo(line)
    click.echo(f"Demo duration     : {result.duration_s:.1f} s")
    sys.exit(result.exit_code)
