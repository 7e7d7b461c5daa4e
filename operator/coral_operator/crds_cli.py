"""Print the CustomResourceDefinitions of coral.dev (or write them into a folder)."""

from __future__ import annotations

from pathlib import Path

import click


@click.command("crds")
@click.option(
    "-o",
    "--output",
    type=click.Path(file_okay=False, path_type=Path),
    help="Write one file per CRD into this folder.",
)
def crds_command(output: Path | None) -> None:
    """Print the CustomResourceDefinitions of coral.dev (or write them into a folder)."""
    from coral_operator.api import crdgen

    rendered = {name: crdgen.render(manifest) for name, manifest in crdgen.build_crds().items()}
    if output is None:
        click.echo("---\n".join(rendered.values()), nl=False)
        return
    output.mkdir(parents=True, exist_ok=True)
    for name, text in rendered.items():
        (output / name).write_text(text)
        click.echo(f"wrote {output / name}")
