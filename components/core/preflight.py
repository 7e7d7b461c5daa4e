"""Preflight: a tree checked against the images that will run it, before any robot moves.

Pure. Given a loaded tree and, per image, what it declares (`image_exports`), it finds what the
executor would refuse on the robot: a behavior none of the images exports, a port the exporting
image does not declare (or a required one left out), and an image built for another Coral major
version or BT.CPP format. Problems read `file:line: message` and name the image. An image that
declares nothing makes the behavior check impossible: it is listed in `undeclared` and the tree is
then left to the robot, as without preflight. Used by the operator's system pass and `coral verify`.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field

from coral_core import bt, names
from coral_core.bt.nodes.base import TreeNode
from coral_core.bt.ports import declared_ports
from coral_core.image_exports import BTCPP_COMPATIBLE, ImageExports, major_of

_UNKNOWN = re.compile(r"Node not recognized: (\w+)")
_PORT = re.compile(r"a port with name \[([^\]]*)\] is found in the XML \(<(\w+)>\).*")
_NODE = re.compile(r"<(\w+)>")


@dataclass(frozen=True)
class Verdict:
    problems: list[str] = field(default_factory=list)
    """Why the tree must not be rolled out, each naming the image (and file:line when in the tree)."""
    undeclared: list[str] = field(default_factory=list)
    """Images that declare nothing: their behaviors are only known on the robot."""

    @property
    def passed(self) -> bool:
        return not self.problems


def version_problems(images: Mapping[str, ImageExports | None], coral_version: str) -> list[str]:
    """Images built for a Coral major version or BT.CPP format other than this one's."""
    problems = []
    for image, exports in sorted(images.items()):
        if exports is None:
            continue
        if major_of(exports.coral_version) != major_of(coral_version):
            problems.append(
                f"image {image} was built for Coral {exports.coral_version}; this is Coral {coral_version} "
                f"(major versions {major_of(exports.coral_version)} and {major_of(coral_version)} differ)"
            )
        if exports.btcpp_version != BTCPP_COMPATIBLE:
            problems.append(
                f"image {image} exports behaviors for BT.CPP format {exports.btcpp_version}, "
                f"not {BTCPP_COMPATIBLE}"
            )
    return problems


def _with_executors() -> bt.NodeRegistry:
    """The built-ins and the executor's own behaviors: the executor's are known to exist, and their
    ports are the executor's to check (registered without ports, their port problems are the same
    with and without the images, so none is reported here)."""
    registry = bt.NodeRegistry.with_builtins()
    for node_id in names.COORDINATION_BEHAVIORS:
        registry.register(node_id, TreeNode, kind="action", ports=[], source="executor")
    return registry


def _registry(images: Mapping[str, ImageExports]) -> tuple[bt.NodeRegistry, dict[str, str], list[str]]:
    """Built-ins plus every declared behavior; which image exports each; behaviors two images export."""
    registry = _with_executors()
    owner: dict[str, str] = {}
    clashes = []
    for image, exports in sorted(images.items()):
        for behavior in exports.behaviors:
            if behavior.id in owner:
                clashes.append(f"behavior {behavior.id} is exported by both {owner[behavior.id]} and {image}")
                continue
            if registry.has(behavior.id):
                continue
            ports = declared_ports(behavior.ports)
            # The class is never built: the registry only lends its kind and ports to validation.
            registry.register(behavior.id, TreeNode, kind=behavior.kind, ports=ports, source=image)
            owner[behavior.id] = image
    return registry, owner, clashes


def _named(
    message: str, at: str | None, registry: bt.NodeRegistry, owner: Mapping[str, str], images: list[str]
) -> str:
    """The engine's message, saying which image it is about; `at` is the node ID on the error's line."""
    unknown = _UNKNOWN.search(message)
    if unknown:
        head = message[: unknown.start()]
        return f"{head}behavior {unknown[1]} is exported by none of the images {', '.join(images)}"
    port = _PORT.search(message)
    if port and port[2] in owner:
        declared = ", ".join(p.name for p in registry.spec(port[2]).ports) or "none"
        return (
            f"{message[: port.start()]}port [{port[1]}] of {port[2]} is not declared by image "
            f"{owner[port[2]]} (it declares: {declared})"
        )
    node = _NODE.search(message)
    named = node[1] if node else at
    if named in owner:
        return f"{message} ({named} as image {owner[named]} declares it)"
    return message


def check_document(
    document: bt.TreeDocument, images: Mapping[str, ImageExports | None], coral_version: str
) -> Verdict:
    """The preflight verdict of a loaded tree run by `images` (reference -> declaration or None)."""
    undeclared = sorted(image for image, exports in images.items() if exports is None)
    problems = version_problems(images, coral_version)
    if undeclared:
        return Verdict(problems, undeclared)
    declared = {image: exports for image, exports in images.items() if exports is not None}
    registry, owner, clashes = _registry(declared)
    # What only the declared behaviors change: problems with built-ins alone are the tree
    # validation's, reported there already.
    baseline = {str(error) for error in bt.validate_document(document, _with_executors())}
    unknown = set(document.missing_node_types(registry))
    at = {
        (element.file, element.line): element.node_id
        for tree in document.trees.values()
        if tree.root is not None
        for element in tree.root.walk()
        if element.node_id in owner
    }
    for error in bt.validate_document(document, registry):
        message = str(error)
        if message in baseline and not any(f"Node not recognized: {node}" in message for node in unknown):
            continue
        problems.append(_named(message, at.get((error.file, error.line)), registry, owner, sorted(declared)))
    return Verdict(problems + clashes, [])
