"""Turn a folder of Coral files (compose, tree XML, parameters YAML) into a CoralSystem."""

from __future__ import annotations

import re
from pathlib import Path

import click

# A namespace is a DNS-1123 label.
NAMESPACE_RE = re.compile(r"^[a-z0-9]([-a-z0-9]{0,61}[a-z0-9])?$")


def _selector(values: tuple[str, ...]) -> dict[str, str]:
    from pydantic import ValidationError

    from coral_operator.api.common import LabelSelector

    result = {}
    for value in values:
        key, sep, label = value.partition("=")
        if not sep or not key:
            raise click.UsageError(f"--robots {value!r}: expected KEY=VALUE")
        try:
            LabelSelector.model_validate({"matchLabels": {key: label}})
        except ValidationError as error:
            first = error.errors()[0]
            reason = (
                f"{label!r} is not a Kubernetes label value (up to 63 letters, digits, '-', '_' and '.', "
                "starting and ending with a letter or digit)"
                if len(first["loc"]) > 1  # the value's own location: ("matchLabels", key)
                else first["msg"].removeprefix("Value error, ")
            )
            raise click.UsageError(f"--robots {value!r}: {reason}") from None
        result[key] = label
    return result


def _checked_namespace(_context: click.Context, _parameter: click.Parameter, value: str | None) -> str | None:
    if value is not None and not NAMESPACE_RE.match(value):
        raise click.BadParameter(
            f"{value!r} is not a namespace name (lowercase letters, digits and '-', at most 63)"
        )
    return value


@click.command("convert")
@click.argument("folder", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--name", help="CoralSystem name; the compose project's name when omitted.")
@click.option("--namespace", callback=_checked_namespace, help="Namespace to put in the manifest.")
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
    from coral_core import names

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
