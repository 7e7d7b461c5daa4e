"""The `coral executor` verb (also `python -m coral.executor`): run one behavior tree."""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from pathlib import Path

import click
from click.decorators import FC
from coral_core.limits import DEFAULT_NO_PROGRESS_S, MAX_TICK_RATE_HZ


def groot2_options(port_help: str) -> Callable[[FC], FC]:
    """`--groot2-port`, `--groot2-allow-hooks` and `--groot2-wait` (parameters `groot2_port`,
    `groot2_allow_hooks`, `groot2_wait_s`) of `coral executor` and `coral run`; the command calls
    `check_groot2_options` with them."""
    port = click.option("--groot2-port", type=click.IntRange(1, 65534), default=None, help=port_help)
    allow_hooks = click.option(
        "--groot2-allow-hooks",
        is_flag=True,
        help="Let Groot2 clients set breakpoints and replace node results (refused by default).",
    )
    wait = click.option(
        "--groot2-wait",
        "groot2_wait_s",
        type=click.FloatRange(min=0.0, max=3600.0),
        default=0.0,
        show_default=True,
        help="Hold each executor's first tick until a Groot2 client sets a hook (or watched for 3 s), "
        "at most this long.",
    )

    def decorate(command: FC) -> FC:
        return port(allow_hooks(wait(command)))

    return decorate


def check_groot2_options(groot2_port: int | None, groot2_allow_hooks: bool, groot2_wait_s: float) -> None:
    if groot2_port is None and (groot2_allow_hooks or groot2_wait_s):
        raise click.UsageError("--groot2-allow-hooks and --groot2-wait need --groot2-port")


def _finite(_context: click.Context, _parameter: click.Parameter, value: float) -> float:
    # A range passes NaN: every comparison with it is false.
    if not math.isfinite(value):
        raise click.BadParameter(f"{value} is not a finite number")
    return value


@click.command("executor")
@click.option(
    "--tree",
    "tree",
    required=True,
    type=click.Path(path_type=Path, dir_okay=False),
    help="BT.CPP v4 XML tree file.",
)
@click.option(
    "--plugins",
    "plugins",
    required=True,
    type=click.Path(path_type=Path, file_okay=False),
    help="Plugin location the components export into.",
)
@click.option(
    "--params",
    "params",
    type=click.Path(path_type=Path, dir_okay=False),
    help="ROS parameters YAML (applied to the executor's node).",
)
@click.option(
    "--rate",
    "rate_hz",
    type=click.FloatRange(min=0.0, min_open=True, max=MAX_TICK_RATE_HZ),
    callback=_finite,
    default=10.0,
    show_default=True,
    help="Tick rate in Hz, and the most the tree is ticked (a wake-up ticks at once after a period).",
)
@click.option(
    "--no-progress",
    "no_progress_s",
    type=click.FloatRange(min=0.0),
    callback=_finite,
    default=DEFAULT_NO_PROGRESS_S,
    show_default=True,
    help="Report no progress once one node has failed the same way for this many seconds (0: never).",
)
@click.option(
    "--status-jsonl",
    type=click.Path(path_type=Path, dir_okay=False),
    help="Append status records to this JSON-lines file.",
)
@click.option("--main-tree", default=None, help="ID of the tree to run (default: the file's main tree).")
@click.option(
    "--hostname",
    default=None,
    help="This executor's name for remote triggers (default: CORAL_HOSTNAME or the host name).",
)
@click.option("--name", "node_name", default="coral_executor", show_default=True, help="ROS node name.")
@click.option(
    "--status-topic", default="/coral/tree_status", show_default=True, help="ROS topic for status records."
)
@click.option(
    "--sink", "extra_sinks", multiple=True, metavar="MODULE:FACTORY", help="Extra status sink (repeatable)."
)
@click.option(
    "--wait-timeout",
    "wait_timeout_s",
    type=float,
    default=None,
    help="Give up (exit 5) when node types are still missing after this many seconds.",
)
@click.option(
    "--liveness-wait",
    "liveness_wait_s",
    type=float,
    default=10.0,
    show_default=True,
    help="Before the first tick, wait up to this long to hear every component in use alive.",
)
@groot2_options("Publish the tree over BT.CPP's Groot2 protocol on this port (and the next), on 127.0.0.1.")
@click.option(
    "--groot2-host",
    default="127.0.0.1",
    show_default=True,
    help="Address the Groot2 publisher binds (the pod's loopback unless told otherwise).",
)
@click.option(
    "--metrics-port",
    type=click.IntRange(1, 65535),
    default=None,
    help="Serve Prometheus metrics (ticks, tree status, behavior results) on this port; off when omitted.",
)
@click.option(
    "--metrics-host",
    default="0.0.0.0",
    show_default=True,
    help="Address the metrics endpoint binds (every address of the pod, for Prometheus to reach).",
)
@click.option("-v", "--verbose", is_flag=True, help="Print every node transition on the terminal.")
def executor_command(
    tree: Path,
    plugins: Path,
    params: Path | None,
    rate_hz: float,
    no_progress_s: float,
    status_jsonl: Path | None,
    main_tree: str | None,
    hostname: str | None,
    node_name: str,
    status_topic: str,
    extra_sinks: tuple[str, ...],
    wait_timeout_s: float | None,
    liveness_wait_s: float,
    groot2_port: int | None,
    groot2_host: str,
    groot2_allow_hooks: bool,
    groot2_wait_s: float,
    metrics_port: int | None,
    metrics_host: str,
    verbose: bool,
) -> None:
    """Run a behavior tree with the behaviors the running components exported."""
    from coral.executor import running

    options = running.ExecutorOptions(
        tree=tree,
        plugins=plugins,
        params=params,
        rate_hz=rate_hz,
        no_progress_s=no_progress_s,
        status_jsonl=status_jsonl,
        main_tree=main_tree,
        node_name=node_name,
        status_topic=status_topic,
        extra_sinks=list(extra_sinks),
        wait_timeout_s=wait_timeout_s,
        liveness_wait_s=liveness_wait_s,
        groot2_port=groot2_port,
        groot2_host=groot2_host,
        groot2_allow_hooks=groot2_allow_hooks,
        groot2_wait_s=groot2_wait_s,
        metrics_port=metrics_port,
        metrics_host=metrics_host,
        verbose=verbose,
    )
    check_groot2_options(groot2_port, groot2_allow_hooks, groot2_wait_s)
    if hostname:
        options.hostname = hostname
    sys.exit(running.run_executor(options))
