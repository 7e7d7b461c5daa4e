"""Turn a folder of Coral files (compose, tree XML, parameters YAML) into a CoralSystem."""

from __future__ import annotations

from pathlib import Path

import click


def _selector(values: tuple[str, ...]) -> dict[str, str]:
    result = {}
    for value in values:
        key, sep, label = value.partition("=")
        if not sep or not key:
            raise click.UsageError(f"--robots {value!r}: expected KEY=VALUE")
        result[key] = label
    return result


@click.command("convert")
@click.argument("folder", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--name", help="CoralSystem name; the compose project's name when omitted.")
@click.option("--namespace", help="Namespace to put in the manifest.")
@click.option(
    "--robots",
    "robots",
    multiple=True,
    help="KEY=VALUE label the robots must carry (repeatable). Default: coral.dev/robot=robot-1.",
)
@click.option("--tree", type=click.Path(exists=True, dir_okay=False, path_type=Path), help="Tree XML file.")
@click.option(
    "--params", type=click.Path(exists=True, dir_okay=False, path_type=Path), help="Parameters YAML."
)
@click.option(
    "-o", "--output", type=click.Path(dir_okay=False, path_type=Path), help="Write here, not stdout."
)
def convert_command(
    folder: Path,
    name: str | None,
    namespace: str | None,
    robots: tuple[str, ...],
    tree: Path | None,
    params: Path | None,
    output: Path | None,
) -> None:
    """Turn a folder of Coral files (compose, tree XML, parameters YAML) into a CoralSystem."""
    from coral_operator.api import names
    from coral_operator.convert import converting
    from coral_operator.convert.compose import ConvertError

    selector = _selector(robots) or {names.LABEL_ROBOT: "robot-1"}
    try:
        manifest, warnings = converting.convert(
            folder=folder, selector=selector, name=name, namespace=namespace, tree=tree, params=params
        )
    except ConvertError as error:
        raise click.ClickException(str(error)) from error
    for warning in warnings:
        click.echo(f"warning: {warning}", err=True)
    flags = "".join(f" --robots {k}={v}" for k, v in selector.items()) + (f" --name {name}" if name else "")
    text = converting.render(manifest, f"coral convert {folder.as_posix().rstrip('/')}{flags}")
    if output:
        output.write_text(text)
    else:
        click.echo(text, nl=False)
