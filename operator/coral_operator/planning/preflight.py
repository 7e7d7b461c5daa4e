"""Preflight of a system pass: each robot's effective tree against the images it will run.

Pure: the reconciler reads what each image declares from its registry (`reconcile.image_exports`)
before the pass, and this decides from that alone. Robots that run the same tree on the same
images are checked once (a fleet of a hundred robots of three models is three checks), and
verdicts are remembered by content in `validation.Verdicts`. An image that declares nothing, or
whose registry could not be read, leaves its robots' trees to be checked on the robot, as without
preflight, and says so in `notes`. See `coral_core.preflight` for what is checked.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import partial
from importlib import metadata
from typing import Any

from coral_core import bt, preflight
from coral_core.bt.limits import IncludeBudget
from coral_core.image_exports import ImageExports

from coral_operator.api.system import CoralSystemSpec
from coral_operator.planning import configmaps, validation
from coral_operator.planning.overrides import ConfigError

CORAL_VERSION = metadata.version("coral-on-kubernetes")
"""The Coral release of this operator: images built for another major version are refused."""
EXPORTING_ROLES = ("drivers", "skillsets")
"""The components whose images export behaviors (executors run them and export none)."""


@dataclass(frozen=True)
class ImageTable:
    """What the reconciler read before the pass: per image reference, its declaration or None (it
    declares nothing), and why images could not be read."""

    exports: Mapping[str, ImageExports | None] = field(default_factory=dict)
    unread: Mapping[str, str] = field(default_factory=dict)
    """Image reference -> why its declaration could not be read (registry unreachable, ...)."""


@dataclass(frozen=True)
class TreeSource:
    text: str
    filename: str
    files: Mapping[str, str]


@dataclass
class PreflightResult:
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    """Images whose trees were left to the robot, and why."""


def images_to_read(spec: CoralSystemSpec) -> list[str]:
    """The exporting images a system's spec names, before any robot's values are substituted: those
    with a `${robot...}` in them are known only per robot, and left to the robot."""
    named = [c.image for role in EXPORTING_ROLES for c in getattr(spec, role)]
    for override in spec.overrides:
        exporting = {c.name for role in EXPORTING_ROLES for c in getattr(spec, role)}
        exporting |= {c.name for role in EXPORTING_ROLES for c in getattr(override.add, role)}
        named += [image for name, image in override.images.items() if name in exporting]
        named += [c.image for role in EXPORTING_ROLES for c in getattr(override.add, role)]
    return sorted({image for image in named if "${" not in image})


def images_of(template: Mapping[str, Any]) -> tuple[str, ...]:
    """The images of a resolved template's exporting components, sorted."""
    return tuple(sorted({c["image"] for role in EXPORTING_ROLES for c in template.get(role) or []}))


def tree_sources(
    config_maps: list[dict[str, Any]], base_name: str, base_filename: str, label: str
) -> dict[str, TreeSource]:
    """The tree ConfigMaps of a pass by name, with the name their messages give them."""
    sources = {}
    for manifest in config_maps:
        data = manifest.get("data") or {}
        if configmaps.TREE_KEY not in data:
            continue
        name = manifest["metadata"]["name"]
        files = {k: v for k, v in data.items() if k != configmaps.TREE_KEY}
        filename = base_filename if name == base_name else f"{label} tree (configmap/{name})"
        sources[name] = TreeSource(data[configmaps.TREE_KEY], filename, files)
    return sources


def check_robots(
    wanted: Mapping[str, Mapping[str, Any] | ConfigError],
    trees: Mapping[str, TreeSource],
    table: ImageTable,
    coral_version: str,
    verdicts: validation.Verdicts | None = None,
) -> PreflightResult:
    """Problems of every robot's tree against its images (each once per distinct pair), and notes."""
    groups: dict[tuple[str, str | None, tuple[str, ...]], list[str]] = {}
    for robot, template in sorted(wanted.items()):
        if isinstance(template, ConfigError):
            continue
        tree = template.get("tree") or {}
        key = (tree.get("configMap", ""), tree.get("mainTreeId"), images_of(template))
        groups.setdefault(key, []).append(robot)
    result = PreflightResult()
    noted: set[str] = set()
    for (config_map, main_tree_id, images), robots in groups.items():
        source = trees.get(config_map)
        if source is None:
            continue
        known = {image: table.exports.get(image) for image in images if image in table.exports}
        for image in images:
            if image in table.unread and image not in noted:
                noted.add(image)
                result.notes.append(
                    f"image {image} could not be read ({table.unread[image]}); not preflighted"
                )
            elif image in table.exports and table.exports[image] is None and image not in noted:
                noted.add(image)
                result.notes.append(
                    f"image {image} declares no behaviors (no label); its trees are checked on the robot"
                )
        if not known or len(known) < len(images):
            # A behavior may come from an image whose declaration is unknown (not read: a registry the
            # operator does not read, or a robot's own value in its name): only versions are checked.
            result.problems += preflight.version_problems(known, coral_version)
            continue
        parts = (
            "preflight",
            source.text,
            source.filename,
            main_tree_id,
            sorted(source.files.items()),
            sorted((image, repr(exports)) for image, exports in known.items()),
            coral_version,
        )
        compute = partial(_check, source, main_tree_id, known, coral_version)
        problems = verdicts.get(parts, compute) if verdicts is not None else compute()
        where = f"robots {', '.join(robots[:3])}" + (
            f" and {len(robots) - 3} more" if len(robots) > 3 else ""
        )
        result.problems += [f"{problem} ({where})" for problem in problems if problem]
    result.problems = list(dict.fromkeys(result.problems))
    return result


def _check(
    source: TreeSource,
    main_tree_id: str | None,
    images: Mapping[str, ImageExports | None],
    coral_version: str,
) -> list[str]:
    try:
        document = bt.load_tree_text(
            source.text,
            filename=source.filename,
            main_tree=main_tree_id,
            resolve_include=validation.include_resolver(
                source.files, IncludeBudget(validation.LIMITS), f"{source.filename} files"
            ),
        )
    except bt.BTLoadError as error:
        # Validated before the pass came here; a tree that fails now is reported there.
        return [str(error)]
    return preflight.check_document(document, images, coral_version).problems
