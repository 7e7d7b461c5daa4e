"""Offline checks of a Coral project: `coral verify`, `coral validate` and `coral nodes-model`.

A component's manifest is obtained the way it is at runtime, without starting ROS: its class is
imported and `coral.plugins.exporting.export_plugin` writes the plugin into a temporary folder,
which `coral.plugins.discovery.inspect_plugin` then reads back exactly as an executor would.
Validation registers every behavior of the listed components (from their manifests, as
placeholder node types carrying the declared kind and ports) beside the engine's built-ins and
collects every static problem of the tree, the parameters file and the compose file, each with
file:line. Called by the verbs in `coral.local.cli`.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from coral_core.compose import ComposeError, Project, Service, find_compose_file, parse_compose

import coral
from coral.local import components


@dataclass
class Verification:
    component: str
    target: str
    manifest: object | None = None  # coral.plugins.manifest.PluginManifest
    problems: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.problems and self.manifest is not None


def verify_target(target: str, name: str | None = None) -> Verification:
    """Exports `target` (`module:Class`) under `name` (default: its NAME) into a scratch folder, checks it."""
    from coral.plugins import compat, discovery, exporting
    from coral.plugins import manifest as manifests
    from coral.sdk import running

    result = Verification(component=name or target, target=target)
    try:
        cls = running.load_component_class(target)
    except (ImportError, ValueError) as err:
        result.problems.append(f"{target}: cannot import the component class: {err}")
        return result
    if name is None:
        from coral.sdk.component import default_component_name

        name = getattr(cls, "NAME", None) or default_component_name(cls)
        result.component = name
    kind = getattr(cls, "KIND", None)
    if kind not in ("skillset", "driver"):
        result.problems.append(
            f"{target}: not a Coral component (KIND is {kind!r}; subclass coral.sdk Skillset/Driver)"
        )
        return result
    with tempfile.TemporaryDirectory(prefix="coral-verify-") as scratch:
        try:
            folder = exporting.export_plugin(
                Path(scratch),
                manifests.ComponentRef(name=name, kind=kind, node_name=name, namespace="/"),
                list(getattr(cls, "BEHAVIORS", ())),
                extra_modules=list(getattr(cls, "EXPORT_MODULES", ())),
                interface_packages=list(getattr(cls, "INTERFACE_PACKAGES", ())),
            )
        except (exporting.ExportError, ValueError, TypeError) as err:
            result.problems.append(f"{target}: export failed: {err}")
            return result
        plugin = discovery.inspect_plugin(
            folder, ros_distro=compat.current_ros_distro(), coral_version=coral.__version__
        )
        if isinstance(plugin, discovery.Refusal):
            result.problems.append(f"{target}: an executor would refuse the plugin: {plugin.reason}")
            return result
        result.manifest = plugin.manifest
    if kind == "skillset" and not result.manifest.behaviors:  # type: ignore[attr-defined]
        result.problems.append(f"{target}: a skillset that exports no behaviors")
    return result


def verify_component(reference: str) -> Verification:
    """`reference` is an image name, an entry-point name or `module:Class`."""
    if ":" in reference and "/" not in reference.split(":", 1)[0] and "." in reference.split(":", 1)[0]:
        return verify_target(reference)
    service = Service(name="component", role="skillset", line=0, image=reference)
    try:
        target = components.component_target(service)
    except components.ComponentNotFound as err:
        return Verification(component=reference, target="", problems=[str(err)])
    return verify_target(target)


def project_manifests(project: Project) -> tuple[dict[str, object], list[str]]:
    """Manifests of the project's drivers and skillsets (by service name) and the problems met."""
    found: dict[str, object] = {}
    problems: list[str] = []
    for service in project.services:
        if service.role == "executor":
            continue
        if service.command is not None and service.image is None and service.component is None:
            continue  # an arbitrary command: nothing to inspect offline
        try:
            target = components.component_target(service)
        except components.ComponentNotFound as err:
            problems.append(f"{project.file}:{service.line}: {err}")
            continue
        verification = verify_target(target, service.name)
        problems += [f"{project.file}:{service.line}: {p}" for p in verification.problems]
        if verification.manifest is not None:
            found[service.name] = verification.manifest
    return found, problems


def registry_for(manifests: dict[str, object]) -> object:
    """The executor's built-ins (the engine's and the coordination behaviors) plus placeholder
    node types for every manifest behavior."""
    from coral_core import bt
    from coral_core.bt import leaves
    from coral_core.bt.ports import declared_ports

    from coral import coordination

    registry = bt.NodeRegistry.with_builtins()
    coordination.register(registry)
    bases = {"action": leaves.SyncAction, "condition": leaves.ConditionNode}
    for component, manifest in sorted(manifests.items()):
        for entry in manifest.behaviors:  # type: ignore[attr-defined]
            if registry.has(entry.id):
                continue
            ports = declared_ports(entry.ports)
            placeholder = type(entry.id, (bases.get(entry.kind, leaves.SyncAction),), {"PORTS": ports})
            registry.register(entry.id, placeholder, kind=entry.kind, ports=ports, source=component)
    return registry


@dataclass
class Report:
    problems: list[str] = field(default_factory=list)  # each `file:line: message`
    warnings: list[str] = field(default_factory=list)


def validate(target: Path) -> Report:
    """Every problem found in the project at `target` (folder or compose file), as `file:line: message`.

    Unset required variables are warnings: they are for the run, and the files can still be checked.
    """
    from coral_core import bt

    from coral.sdk import params

    try:
        project = parse_compose(find_compose_file(Path(target)), lenient=True)
    except ComposeError as err:
        return Report(problems=[str(err)])
    problems: list[str] = []
    if project.params is not None:
        try:
            params.validate_file(project.params)
        except params.ParamsError as err:
            problems.append(str(err))
    manifests, manifest_problems = project_manifests(project)
    problems += manifest_problems
    if project.tree is not None:
        registry = registry_for(manifests)
        try:
            document = bt.load_tree_file(project.tree, registry, main_tree=project.main_tree)
            problems += [str(error) for error in bt.validate_document(document, registry)]
        except bt.BTError as err:
            problems.append(str(err))
    return Report(problems=problems, warnings=project.warnings)


def nodes_model(target: Path | None, references: list[str]) -> tuple[str, list[str]]:
    """The `<TreeNodesModel>` XML for a project's components or for named components."""
    from coral_core.bt import treenodesmodel

    from coral.plugins import manifest as plugin_manifests

    manifests: dict[str, object] = {}
    problems: list[str] = []
    if target is not None:
        try:
            project = parse_compose(find_compose_file(Path(target)), lenient=True)
        except ComposeError as err:
            return "", [str(err)]
        manifests, problems = project_manifests(project)
    for reference in references:
        verification = verify_component(reference)
        problems += verification.problems
        if verification.manifest is not None:
            manifests[verification.component] = verification.manifest
    palette = plugin_manifests.palette_behaviors(manifests.values())  # type: ignore[arg-type]
    return treenodesmodel.build_tree_nodes_model(palette), problems
