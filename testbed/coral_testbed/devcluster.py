"""`coral dev-cluster`: a cluster to try Coral on. Its own verbs make a kind cluster of robots, one
kind worker per robot (`coral_testbed.kind.cli`); `local` runs the suite's own control plane of
host processes (`coral_testbed.cluster.cli`), which the operator tests and the fleet benchmark's
default still use. Registered as a `coral.verbs` entry point (setup.py)."""

from __future__ import annotations

import click

from coral_testbed.cluster import cli as local_cli
from coral_testbed.kind import cli as kind_cli

dev_cluster = click.Group(
    "dev-cluster",
    help="A kind cluster of robots to try Coral on (docs/kind.md); `local`: the suite's own control plane.",
    commands=[*kind_cli.COMMANDS, local_cli.local],
)
