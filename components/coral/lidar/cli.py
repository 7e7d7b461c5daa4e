"""The `coral generate-bag` and `coral slam-demo` verbs (thin: options in, one library call)."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from coral import terminal
from coral.lidar import generating

DEFAULT_EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "lidar-slam"


def bag_options(function: click.decorators.FC) -> click.decorators.FC:
    defaults = generating.BagParams()
    for option in reversed(
        [
            click.option(
                "--seed", type=int, default=defaults.seed, show_default=True, help="Scene and noise seed."
            ),
            click.option(
                "--scans",
                type=click.IntRange(min=2),
                default=defaults.scans,
                show_default=True,
                help="Number of 10 Hz sweeps.",
            ),
            click.option(
                "--beams",
                type=click.IntRange(min=2),
                default=defaults.beams,
                show_default=True,
                help="Lasers per column.",
            ),
            click.option(
                "--columns",
                type=click.IntRange(min=16),
                default=defaults.columns,
                show_default=True,
                help="Firing columns per sweep.",
            ),
            click.option(
                "--speed", type=float, default=defaults.speed, show_default=True, help="Metres per second."
            ),
        ]
    ):
        function = option(function)
    return function


@click.command("generate-bag")
@bag_options
@click.option(
    "--output",
    type=click.Path(path_type=Path, file_okay=False),
    default=None,
    help="Dataset folder to create (default: the cache, ~/.cache/coral-on-kubernetes/bags/...).",
)
def generate_bag_command(
    seed: int, scans: int, beams: int, columns: int, speed: float, output: Path | None
) -> None:
    """Write a synthetic LiDAR ROS 2 bag (PointCloud2 + ground truth) from a seed; print its folder."""
    params = generating.BagParams(seed=seed, scans=scans, beams=beams, columns=columns, speed=speed)
    try:
        with terminal.progress("Generating the bag", stream=sys.stderr) as step:
            folder = (
                generating.generate(params, output, step)
                if output
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
@click.option(
    "--output",
    "output_dir",
    type=click.Path(path_type=Path, file_okay=False),
    default=Path("out/lidar-slam"),
    show_default=True,
    help="Where the map and trajectory go.",
)
@click.option("--live/--no-live", default=None, help="Live tree view (default: on a terminal).")
@click.option(
    "--tree-png",
    type=click.Path(path_type=Path, dir_okay=False),
    default=None,
    help="Also draw the behavior tree here, each node coloured by its last status.",
)
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

    params = generating.BagParams(seed=seed, scans=scans, beams=beams, columns=columns, speed=speed)
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
