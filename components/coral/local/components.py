"""Decides the local command line of each compose service (pure, apart from reading entry points).

Resolution order for drivers and skillsets:
1. `x-coral.command` in the compose file (placeholders filled in by `render_command`);
2. `x-coral.component`, or the service's image name, looked up in the entry-point group
   `coral.components` (name: the image repository without registry and tag, e.g.
   `coral/slam-skillset`, or just its last segment `slam-skillset`; value: `module:Class` of a
   `coral.sdk` component), run with `python -m coral.sdk.run`;
3. the reference components built into this package (same names), so a source checkout works
   before its entry points are installed.
Executors run `python -m coral.executor` with the project's tree and parameters.
Called by `coral.local.running`, `coral verify` and `coral validate`.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from coral_core.compose import Project, Service

ENTRY_POINT_GROUP = "coral.components"
REFERENCE_COMPONENTS = {
    "coral/bag-player": "coral_drivers.bag_player.driver:BagPlayer",
    "coral/slam-skillset": "coral_skillsets.slam.skillset:SlamSkillset",
    "coral/snapshot-skillset": "coral_skillsets.snapshot.skillset:SnapshotSkillset",
    "coral/examples-skillset": "coral_skillsets.examples.skillset:ExampleSkillset",
}


class ComponentNotFound(LookupError):
    """No command and no installed component for a service; the message says what was tried."""


@dataclass(frozen=True)
class Paths:
    plugins: Path
    output: Path
    status_jsonl: Path


def image_repository(image: str) -> str:
    """`ghcr.io/acme/slam-skillset:1.2@sha256:..` -> `acme/slam-skillset` (registry, tag, digest dropped)."""
    name = image.split("@", 1)[0]
    last_slash = name.rfind("/")
    if name.rfind(":") > last_slash:
        name = name[: name.rfind(":")]
    parts = name.split("/")
    if len(parts) > 1 and ("." in parts[0] or ":" in parts[0] or parts[0] == "localhost"):
        parts = parts[1:]
    return "/".join(parts)


def installed_components() -> dict[str, str]:
    """Entry-point name -> `module:Class`, reference components first so installed ones override."""
    found = dict(REFERENCE_COMPONENTS)
    for entry in metadata.entry_points(group=ENTRY_POINT_GROUP):
        found[entry.name] = entry.value
    return found


def component_target(service: Service, known: dict[str, str] | None = None) -> str:
    """`module:Class` of the component a driver or skillset service runs."""
    known = installed_components() if known is None else known
    wanted = service.component or (image_repository(service.image) if service.image else None)
    if wanted is None:
        raise ComponentNotFound(f"service {service.name} has neither an image nor x-coral.component")
    for candidate in (wanted, wanted.rsplit("/", 1)[-1]):
        if candidate in known:
            return known[candidate]
    tail = wanted.rsplit("/", 1)[-1]
    for name, target in known.items():
        if name.rsplit("/", 1)[-1] == tail:
            return target
    raise ComponentNotFound(
        f"service {service.name}: no installed component named {wanted!r} (entry-point group "
        f"{ENTRY_POINT_GROUP}; known: {', '.join(sorted(known))}); set x-coral.command to run it another way"
    )


def render_command(template: list[str], project: Project, service: Service, paths: Paths) -> list[str]:
    # The keys are compose.COMMAND_PLACEHOLDERS, which the compose parser checks commands against.
    values = {
        "plugins": str(paths.plugins),
        "params": str(project.params or ""),
        "tree": str(project.tree or ""),
        "name": service.name,
        "output": str(paths.output),
        "python": sys.executable,
    }
    try:
        return [part.format(**values) for part in template]
    except (KeyError, IndexError, ValueError) as err:
        raise ComponentNotFound(f"service {service.name}: bad placeholder in x-coral.command: {err}") from err


def command_for(
    project: Project, service: Service, paths: Paths, known: dict[str, str] | None = None
) -> list[str]:
    """The argv that runs `service` as a local process."""
    if service.command is not None:
        return render_command(service.command, project, service, paths)
    if service.role == "executor":
        module, first = "coral.executor", ["--tree", str(project.tree)]
        middle = ["--status-jsonl", str(paths.status_jsonl)]
    else:
        module, first, middle = "coral.sdk.run", [component_target(service, known)], []
    argv = [
        sys.executable,
        "-m",
        module,
        *first,
        "--plugins",
        str(paths.plugins),
        *middle,
        "--name",
        service.name,
    ]
    if project.params is not None:
        argv += ["--params", str(project.params)]
    if service.role == "executor":
        main_tree = service.main_tree or project.main_tree
        if main_tree:
            argv += ["--main-tree", main_tree]
        rate = service.rate or project.rate
        if rate:
            argv += ["--rate", f"{rate:g}"]
        argv += groot2_arguments(project, service)
    return argv


def groot2_arguments(project: Project, service: Service) -> list[str]:
    """The executor's Groot2 flags: each executor gets its own pair of ports."""
    if project.groot2_port is None:
        return []
    index = [s.name for s in project.by_role("executor")].index(service.name)
    argv = ["--groot2-port", str(project.groot2_port + 2 * index)]
    if project.groot2_allow_hooks:
        argv.append("--groot2-allow-hooks")
    if project.groot2_wait_s:
        argv += ["--groot2-wait", f"{project.groot2_wait_s:g}"]
    return argv
