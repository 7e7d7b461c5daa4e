"""Run the Coral operator (watches CoralSystems and CoralInstances)."""

from __future__ import annotations

import signal
import sys
import threading
from types import FrameType

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
@click.option(
    "--metrics",
    default=None,
    envvar="CORAL_OPERATOR_METRICS",
    metavar="ADDRESS:PORT",
    help="Serve Prometheus metrics on http://ADDRESS:PORT/metrics, for example 0.0.0.0:8081 "
    "(env CORAL_OPERATOR_METRICS); off when omitted.",
)
@click.option("-v", "--verbose", is_flag=True, help="Log every handler run.")
def operator_command(
    namespaces: tuple[str, ...], liveness: str | None, metrics: str | None, verbose: bool
) -> None:
    """Run the Coral operator (watches CoralSystems and CoralInstances)."""
    stop_on_sigterm_while_loading()
    from coral_operator import main

    main.run(
        namespaces=list(namespaces),
        verbose=verbose,
        liveness=liveness,
        metrics=None if metrics is None else _address(metrics),
    )


def _address(value: str) -> tuple[str, int]:
    address, _, port = value.rpartition(":")
    if not address or not port.isdigit() or not 0 < int(port) < 65536:
        raise click.BadParameter(
            f"{value!r} is not ADDRESS:PORT, for example 0.0.0.0:8081", param_hint="--metrics"
        )
    return address, int(port)


def stop_on_sigterm_while_loading() -> None:
    """Exit on SIGTERM until kopf takes the signal over.

    In its pod the operator is the container's first process, and the kernel drops a signal whose
    action is the default for such a process: a pod deleted while the operator still loads (a
    `helm upgrade` seconds after the last one) would sit out its whole grace period before the
    kubelet kills it, and the next operator (the chart's `Recreate`) wait as long to start.
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _exit_on_sigterm)


def _exit_on_sigterm(signum: int, _frame: FrameType | None) -> None:
    sys.exit(128 + signum)
