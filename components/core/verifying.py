"""The operator's preflight for `coral verify`: images' declarations from their registry, and a tree
checked against them, so CI refuses what the operator would refuse.

Each image's declaration (`image_exports`) is read by digest (`image_labels`); its Coral version is
checked against this Coral's and, given a tree, every behavior the tree uses must be exported by
one of the images with the ports it is given. An image that declares nothing passes as the
operator lets it pass, with a note: its trees are checked on the robot. Called by
`coral.local.cli.verify_command`.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

from coral_core import bt, image_exports, image_labels, preflight


@dataclass
class Report:
    lines: list[str] = field(default_factory=list)
    """Notes: images whose trees are left to the robot."""
    problems: list[str] = field(default_factory=list)
    """What the operator would refuse, or what could not be read."""


def docker_auths(path: Path | None) -> dict[str, Any]:
    """The `auths` of a Docker config file (a pull secret's `.dockerconfigjson` has the same shape);
    `~/.docker/config.json` when no path is given, and none when that does not exist.

    Raises:
        ValueError: the file given does not exist or is not a Docker config.
    """
    candidate = path or Path.home() / ".docker" / "config.json"
    if not candidate.is_file():
        if path is not None:
            raise ValueError(f"{path} does not exist")
        return {}
    try:
        auths = json.loads(candidate.read_text(encoding="utf-8")).get("auths") or {}
    except (ValueError, AttributeError) as error:
        raise ValueError(f"{candidate} is not a Docker config: {error}") from error
    return dict(auths)


def describe(image: str, exports: image_exports.ImageExports | None) -> str:
    if exports is None:
        return f"{image}: declares nothing (no {image_exports.EXPORTS_LABEL} label)"
    ids = ", ".join(b.id for b in exports.behaviors) or "no behaviors"
    return (
        f"{image}: {exports.kind} {exports.component}, Coral {exports.coral_version}, "
        f"BT.CPP {exports.btcpp_version}, ROS {exports.ros_distro}: {ids}"
    )


def check(
    declared: Mapping[str, image_exports.ImageExports | None],
    tree: Path | None,
    main_tree: str | None = None,
    coral_version: str | None = None,
) -> Report:
    """The preflight of `tree` (or of the versions alone) against what the images declare."""
    version = coral_version or metadata.version("coral-on-kubernetes")
    report = Report()
    if tree is None:
        report.problems = preflight.version_problems(declared, version)
        return report
    try:
        document = bt.load_tree_text(
            tree.read_text(encoding="utf-8"), filename=str(tree), main_tree=main_tree
        )
    except bt.BTLoadError as error:
        report.problems = [str(error)]
        return report
    verdict = preflight.check_document(document, declared, version)
    report.problems = verdict.problems
    report.lines = [
        f"note: {image} declares nothing; the tree is checked on the robot" for image in verdict.undeclared
    ]
    return report


def read_declarations(
    images: Sequence[str], auths: Mapping[str, Any], timeout: float = image_labels.TIMEOUT_SECONDS
) -> tuple[dict[str, image_exports.ImageExports | None], list[str]]:
    """(image -> declaration or None, why images could not be read)."""
    reader = image_labels.ImageLabels(timeout=timeout)
    declared: dict[str, image_exports.ImageExports | None] = {}
    errors = []
    for image in images:
        try:
            digest, labels = reader.labels(image, auths)
            named = image if "@" in image else f"{image}@{digest}"
            declared[named] = image_exports.from_labels(labels, image)
        except (image_labels.LabelsError, image_exports.ExportsError) as error:
            errors.append(str(error))
    return declared, errors
