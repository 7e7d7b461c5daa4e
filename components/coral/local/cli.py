"""Thin `coral` verbs of the local runtime: run, ps, stop, logs, validate, verify, nodes-model.

Each verb parses its options and calls one function of `coral.local.running`, `coral.local.state`
or `coral.local.checking`; registered as `coral.verbs` entry points (setup.py).
"""

from __future__ import annotations

import os
import signal
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import click
from coral_core import logs_verb, parsing, polling
from rich.text import Text

from coral.executor.cli import check_groot2_options, groot2_options
from coral.local import state

# How `coral ps` colours run and component states on a terminal.
RUN_STATE_STYLE = {
    "running": "green",
    "ready": "green",
    "starting": "yellow",
    "stopping": "yellow",
    "pending": "bright_black",
    "finished": "bright_black",
    "exited": "bright_black",
    "stopped": "bright_black",
    "failed": "red",
}

TARGET = click.argument("target", type=click.Path(exists=True, path_type=Path))


def output_option(default: Path | None, text: str) -> Callable[[click.decorators.FC], click.decorators.FC]:
    """`--output DIR` (parameter `output_dir`) of `coral run`, `coral slam-demo` and `coral demo`."""
    return click.option(
        "--output",
        "output_dir",
        type=click.Path(path_type=Path, file_okay=False),
        default=default,
        show_default=default is not None,
        help=text,
    )


# Shared by `coral run`, `coral slam-demo` and `coral demo`.
TREE_PNG = click.option(
    "--tree-png",
    type=click.Path(path_type=Path, dir_okay=False),
    default=None,
    help="When the mission ends, draw its behavior tree into this PNG, nodes coloured by last status.",
)


def _checked_handle(_context: click.Context, _parameter: click.Parameter, value: str | None) -> str | None:
    # The handle names the run's folder: it must stay one plain name inside the runs folder.
    if value is not None and not state.HANDLE_RE.match(value):
        raise click.BadParameter(
            f"{value!r}: use letters, digits, '.', '_' and '-', starting with a letter or digit"
        )
    return value


@click.command("run")
@TARGET
@click.option(
    "--handle",
    default=None,
    callback=_checked_handle,
    help="Name of this instance (default: <project>-<random>).",
)
@click.option("--group", default=None, help="Group for `coral stop --group` (default: the project name).")
@output_option(None, "Folder for what components write ($CORAL_OUTPUT_DIR; default: ./out/<project>).")
@click.option("--detach", "-d", is_flag=True, help="Run in the background; print the handle.")
@click.option(
    "--live/--no-live", default=None, help="Live tree view (default: on when stdout is a terminal)."
)
@click.option(
    "--env", "env_pairs", multiple=True, metavar="KEY=VALUE", help="Extra environment for components."
)
@TREE_PNG
@groot2_options("Executors publish their trees over Groot2's protocol on 127.0.0.1 from this port, two each.")
def run_command(
    target: Path,
    handle: str | None,
    group: str | None,
    output_dir: Path | None,
    detach: bool,
    live: bool | None,
    env_pairs: tuple[str, ...],
    tree_png: Path | None,
    groot2_port: int | None,
    groot2_allow_hooks: bool,
    groot2_wait_s: float,
) -> None:
    """Run a Coral project (compose file, tree, parameters) as local processes."""
    from coral_core import compose

    from coral.local import running

    check_groot2_options(groot2_port, groot2_allow_hooks, groot2_wait_s)
    groot2 = running.Groot2Settings(groot2_port, groot2_allow_hooks, groot2_wait_s)

    extra_env = dict(pair.split("=", 1) for pair in env_pairs if "=" in pair)
    if detach:
        if env_pairs:
            raise click.UsageError("--env cannot be combined with --detach; export the variables instead")
        try:
            print(
                running.start_detached(
                    target,
                    handle=handle,
                    group=group,
                    output_dir=output_dir,
                    tree_png=tree_png,
                    groot2=groot2,
                )
            )
        except (compose.ComposeError, RuntimeError) as err:
            raise click.ClickException(str(err)) from err
        return
    sys.exit(
        running.run_project(
            target,
            handle=handle,
            group=group,
            output_dir=output_dir,
            live=live,
            extra_env=extra_env,
            tree_png=tree_png,
            groot2=groot2,
        )
    )


@click.command("ps")
@click.option("--all", "-a", "everything", is_flag=True, help="Include finished runs.")
def ps_command(everything: bool) -> None:
    """List Coral runs on this machine and their components."""
    from coral_core import terminal

    runs = [r for r in state.load_runs() if everything or r.state != "finished"]
    if not runs:
        click.echo("no runs" if everything else "no running instances (use -a for finished ones)")
        return
    rows = []
    for run in runs:
        components = Text(", ").join(
            Text.assemble(
                f"{c.name}({c.role[0]}):",
                (
                    c.state + (f"/{c.exit_code}" if c.exit_code is not None else ""),
                    RUN_STATE_STYLE.get(c.state, ""),
                ),
            )
            for c in run.components
        )
        state_text = run.state if run.exit_code is None else f"{run.state}({run.exit_code})"
        age = f"{time.time() - run.started_at:.0f}s"
        rows.append(
            [run.handle, run.group, Text(state_text, RUN_STATE_STYLE.get(run.state, "")), age, components]
        )
    terminal.console().print(
        terminal.table(["HANDLE", "GROUP", "STATE", "AGE", "COMPONENTS"], rows, right=["AGE"])
    )


@click.command("stop")
@click.option("--handle", default=None, help="Stop the run with this handle.")
@click.option("--group", default=None, help="Stop every run of this group.")
@click.option("--all", "everything", is_flag=True, help="Stop every run.")
@click.option("--timeout", default=30.0, show_default=True, help="Seconds to wait for each run to end.")
def stop_command(handle: str | None, group: str | None, everything: bool, timeout: float) -> None:
    """Stop runs: components end in reverse order (executors, skillsets, drivers)."""
    if sum(bool(x) for x in (handle, group, everything)) != 1:
        raise click.UsageError("give exactly one of --handle, --group, --all")
    selected = state.select_runs(state.load_runs(), handle=handle, group=group, everything=everything)
    # A supervisor that was killed cannot stop its components: end their process groups here.
    for run in selected:
        for orphan in state.orphaned_components(run):
            click.echo(f"{run.handle}: killing {orphan.name} (pid {orphan.pid}) left by a dead supervisor")
            state.kill_group(orphan.pid)
    runs = [r for r in selected if r.state != "finished"]
    if not runs and not selected:
        raise click.ClickException("no matching run")
    if not runs:
        return
    for run in runs:
        try:
            os.kill(run.supervisor_pid, signal.SIGINT)
        except ProcessLookupError:
            continue
    pending = list(runs)

    def all_stopped() -> bool:
        pending[:] = [r for r in pending if state.pid_alive(r.supervisor_pid)]
        return not pending

    polling.poll_until(all_stopped, timeout_s=timeout, interval_s=0.1)
    for run in runs:
        click.echo(f"{run.handle}: {'still stopping' if run in pending else 'stopped'}")
    if pending:
        sys.exit(1)


@click.command("logs")
@click.argument("handle")
@click.argument("services", nargs=-1)
@click.option("--follow", "-f", is_flag=True, help="Keep printing new lines until the run ends.")
def logs_command(handle: str, services: tuple[str, ...], follow: bool) -> None:
    """Print the logs of a run's components (all, or the SERVICES named)."""
    runs = state.select_runs(state.load_runs(), handle=handle, group=None, everything=False)
    if not runs:
        raise click.ClickException(f"no run with handle {handle}")
    run = runs[0]
    names = list(services) or [c.name for c in run.components]
    unknown = sorted(set(names) - {c.name for c in run.components})
    if unknown:
        raise click.ClickException(f"run {handle} has no component(s) {unknown}")
    offsets = dict.fromkeys(names, 0)
    while True:
        for name in names:
            path = run.folder / f"{name}.log"
            if not path.exists():
                continue
            with path.open("rb") as handle_:
                handle_.seek(offsets[name])
                for raw in handle_:
                    click.echo(f"{name} | {raw.decode('utf-8', errors='replace').rstrip()}")
                offsets[name] = handle_.tell()
        if not follow or not state.pid_alive(run.supervisor_pid):
            return
        time.sleep(0.2)  # tailing files: no event to wait on


def _names_a_run(args: Sequence[str]) -> bool:
    """`coral logs ARGS` is about a run on this machine: they parse as this verb's and name its handle."""
    try:
        with logs_command.make_context("logs", list(args), resilient_parsing=True) as ctx:
            handle = ctx.params.get("handle")
    except click.ClickException:
        return False
    return bool(handle) and bool(
        state.select_runs(state.load_runs(), handle=handle, group=None, everything=False)
    )


LOGS_OF_RUNS = logs_verb.LogsSource(command=logs_command, claims=_names_a_run)
"""`coral logs HANDLE`: registered in `coral_core.logs_verb.LOGS_GROUP` (setup.py)."""


def _user_text(data: bytes, source: str) -> str:
    try:
        return parsing.decode(data)
    except parsing.NotText as err:
        raise click.ClickException(f"{source}:{err.line}: {err.reason}") from None


@click.command("validate")
@click.argument("target", type=click.Path(exists=True, allow_dash=True, path_type=Path))
def validate_command(target: Path) -> None:
    """Check a project's tree against its components' manifests, its parameters and compose file.

    TARGET is a project (folder or compose file), or Kubernetes manifests holding CoralSystems (a
    mission file, or `-` to read them from stdin, e.g. `kubectl kustomize DIR | coral validate -`).
    """
    from coral.local import checking, manifest_checking

    if str(target) == "-":
        text = _user_text(sys.stdin.buffer.read(), "<stdin>")
        report = manifest_checking.validate_manifests(text, "<stdin>")
    elif target.is_file() and manifest_checking.looks_like_manifests(target.read_text(errors="replace")):
        source = str(target)
        report = manifest_checking.validate_manifests(_user_text(target.read_bytes(), source), source)
    else:
        report = checking.validate(target)
    for warning in report.warnings:
        click.echo(f"warning: {warning}", err=True)
    for problem in report.problems:
        click.echo(problem, err=True)
    if report.problems:
        sys.exit(1)
    click.echo(f"{target}: valid")


@click.command("verify")
@click.argument("components", nargs=-1, required=True)
@click.option(
    "--registry",
    "from_registry",
    is_flag=True,
    help="COMPONENTS are images in a registry: check what they declare, as the operator's preflight does.",
)
@click.option(
    "--tree",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    default=None,
    help="A tree XML to check against the components' behaviors and ports.",
)
@click.option("--main-tree", default=None, help="The tree's main BehaviorTree ID.")
@click.option(
    "--coral-version", default=None, help="The Coral release to check images against (default: this one)."
)
@click.option(
    "--docker-config",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Registry credentials (default: ~/.docker/config.json).",
)
@click.option(
    "--print-label",
    is_flag=True,
    help="Print only the dev.coral.exports label of the (installed) component, for `docker build --label`.",
)
def verify_command(
    components: tuple[str, ...],
    from_registry: bool,
    print_label: bool,
    tree: Path | None,
    main_tree: str | None,
    coral_version: str | None,
    docker_config: Path | None,
) -> None:
    """Check that COMPONENTS (image names, entry-point names or module:Class) export valid manifests,
    and that a tree uses only what they export. With --registry, read the images' declarations
    from their registry by digest instead of the installed components (for CI)."""
    from coral_core import verifying

    from coral.local import checking

    problems: list[str] = []
    declared = {}
    if print_label:
        if from_registry or len(components) != 1:
            raise click.UsageError("--print-label takes one installed component")
        result = checking.verify_component(components[0])
        if not result.ok:
            raise click.ClickException("; ".join(result.problems))
        click.echo(result.manifest.image_exports().to_label())  # type: ignore[attr-defined]
        return
    if from_registry:
        try:
            auths = verifying.docker_auths(docker_config)
        except ValueError as error:
            raise click.BadParameter(str(error), param_hint="--docker-config") from error
        declared, problems = verifying.read_declarations(components, auths)
        for image, exports in declared.items():
            click.echo(verifying.describe(image, exports))
    else:
        for component in components:
            result = checking.verify_component(component)
            problems += result.problems
            if result.ok:
                manifest = result.manifest
                declared[component] = manifest.image_exports()  # type: ignore[attr-defined]
                behaviors = [b.id for b in manifest.behaviors]  # type: ignore[attr-defined]
                click.echo(
                    f"{component}: valid {manifest.component.kind} {result.component!r} "  # type: ignore[attr-defined]
                    f"exporting {len(behaviors)} behavior(s): {', '.join(behaviors) or '-'}"
                )
    report = verifying.check(declared, tree, main_tree, coral_version)
    for line in report.lines:
        click.echo(line)
    for problem in problems + report.problems:
        click.echo(f"refused: {problem}", err=True)
    if problems or report.problems:
        sys.exit(1)
    if tree is not None:
        click.echo(f"{tree}: valid on {', '.join(declared)}")


@click.command("nodes-model")
@click.argument("target", required=False, type=click.Path(exists=True, path_type=Path))
@click.option("--component", "references", multiple=True, help="Image name or module:Class (repeatable).")
def nodes_model_command(target: Path | None, references: tuple[str, ...]) -> None:
    """Print the <TreeNodesModel> (Groot2 palette) of a project's components or of named ones."""
    from coral.local import checking

    if target is None and not references:
        raise click.UsageError("give a project folder/compose file or at least one --component")
    xml, problems = checking.nodes_model(target, list(references))
    for problem in problems:
        click.echo(problem, err=True)
    click.echo(xml)
    if problems:
        sys.exit(1)
