"""`coral images`: build the project's images and run the local registry they are pushed to.

Thin verbs over `building` and `registry`; registered as a `coral.verbs` entry point (setup.py).
Progress goes to stderr; `build` prints one line per image on stdout (name, reference, image ID,
size, outcome).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

from coral_testbed import clierrors
from coral_testbed.images import buildah, building, catalog, registry, rootfs

_fail_on_errors = clierrors.fail_on(
    building.ImageBuildError,
    buildah.BuildahError,
    registry.RegistryError,
    rootfs.RootfsError,
    ValueError,
)


def _address_option(command: Callable[..., Any]) -> Callable[..., Any]:
    return click.option(
        "--registry",
        "address",
        default=registry.configured_address,
        show_default="$CORAL_REGISTRY or 127.0.0.1:5000",
        help="HOST:PORT of the local registry.",
    )(command)


@click.group("images")
def images() -> None:
    """Build the project's images with buildah and serve them from a local registry."""


@images.command("build")
@click.argument("names", nargs=-1)
@_address_option
@click.option("--no-push", is_flag=True, help="Build into the local store only; start no registry.")
@_fail_on_errors
def build_command(names: tuple[str, ...], address: str, no_push: bool) -> None:
    """Build NAMES (default: all) and the images they start FROM; push them to the registry.

    Unchanged images are not rebuilt. The registry is started on --registry when it is not
    serving already, and keeps running (`coral images registry down` stops it).
    """
    unknown = [n for n in names if n not in catalog.by_name()]
    if unknown:
        raise click.UsageError(f"unknown image {', '.join(unknown)}; known: {', '.join(catalog.by_name())}")
    if no_push:
        built = building.build(names or None)
    else:
        built = building.publish(address, names or None)
    tool = building.builder()
    click.echo(f"{'NAME':<18} {'REFERENCE':<55} {'IMAGE ID':<12}  {'UNPACKED':>8}  {'PULL':>8}  OUTCOME")
    for name, image in built.items():
        where = image.local_reference if no_push else image.registry_reference(address)
        pull = "-" if no_push else f"{_pull_megabytes(address, image.spec):.1f} MB"
        unpacked = tool.unpacked_size(image.local_reference)
        click.echo(f"{name:<18} {where:<55} {image.image_id[:12]}  {unpacked:>8}  {pull:>8}  {image.outcome}")


def _pull_megabytes(address: str, spec: catalog.ImageSpec) -> float:
    """Compressed size of the image's layers: what a node downloads when it has none of them."""
    found = registry.manifest(address, spec.repository, spec.tag)
    return 0.0 if found is None else sum(size for _, size in found.layers) / 1e6


@images.command("list")
def list_command() -> None:
    """The images the project builds, with their Dockerfiles."""
    for spec in catalog.IMAGES:
        parents = ", ".join(f"{arg}={parent}" for arg, parent in spec.parents.items()) or "-"
        click.echo(f"{spec.name:<18} {spec.reference:<42} {spec.dockerfile:<44} {parents}")


@images.group("registry")
def registry_group() -> None:
    """The local registry (docker-registry, storage under ~/.cache/coral-on-kubernetes/registry)."""


@registry_group.command("up")
@_address_option
@_fail_on_errors
def registry_up(address: str) -> None:
    """Start a registry on --registry unless one is running there; prints its address."""
    _, started = registry.up(address, building.registry_storage(), building.registry_state_dir())
    building.say(f"registry {'started' if started else 'already running'} on {address}")
    click.echo(address)


@registry_group.command("down")
@_address_option
@_fail_on_errors
def registry_down(address: str) -> None:
    """Stop the registry `registry up` started on --registry."""
    stopped = registry.down(building.registry_state_dir(), address)
    building.say(f"registry on {address} {'stopped' if stopped else 'was not running'}")


@registry_group.command("status")
def registry_status() -> None:
    """Addresses of the running registries and the repositories they hold."""
    for address in registry.recorded_addresses(building.registry_state_dir()):
        click.echo(f"{address}  {' '.join(registry.repositories(address))}")
