"""Run the Coral operator (watches CoralSystems and CoralInstances)."""

from __future__ import annotations

import click


@click.command("operator")
@click.option(
    "-n",
    "--namespace",
    "namespaces",
    multiple=True,
    help="Namespace to serve (repeatable); all namespaces when omitted.",
)
@click.option("--liveness", default=None, help="Liveness endpoint, for example http://0.0.0.0:8080/healthz.")
@click.option("-v", "--verbose", is_flag=True, help="Log every handler run.")
def operator_command(namespaces: tuple[str, ...], liveness: str | None, verbose: bool) -> None:
    """Run the Coral operator (watches CoralSystems and CoralInstances)."""
    from coral_operator import main

    main.run(namespaces=list(namespaces), verbose=verbose, liveness=liveness)
