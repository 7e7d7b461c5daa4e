"""The images the project builds: which Dockerfile, which context, which image each one starts FROM.

One entry per Dockerfile in the repository, plus the base that stands in for Docker Hub here: a
Debian bookworm Python made from Debian packages. (The robots' sandbox and test images need no
registry: `coral_testbed.cluster.nodeimages` imports them into each robot.) Repositories are
named as on Docker Hub (`coral/executor`), so robots pull `coral.local/coral/executor:0.1.0` or
`127.0.0.1:5000/coral/executor:0.1.0` (docs/images.md). Pure data, read by `building`.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable
from dataclasses import dataclass, field
from importlib import metadata

VERSION = metadata.version("coral-on-kubernetes")


class Context(enum.Enum):
    """Where an image's build context comes from."""

    REPOSITORY = "repository"
    """The repository root, filtered by its .dockerignore (the project's own Dockerfiles)."""
    DEBIAN_ROOTFS = "debian-rootfs"
    """A folder holding rootfs.tar, the Debian root filesystem made by `rootfs`."""


@dataclass(frozen=True)
class ImageSpec:
    name: str
    """Short name used by the CLI and the API (`runtime`, `executor`)."""
    repository: str
    """Repository in the registry, as on Docker Hub."""
    tag: str
    dockerfile: str
    """Path from the repository root."""
    context: Context
    parents: dict[str, str] = field(default_factory=dict)
    """Build argument -> name of the catalog image it is set to (the FROM of the Dockerfile)."""

    @property
    def reference(self) -> str:
        return f"{self.repository}:{self.tag}"


_RUNTIME_CHILD = {"RUNTIME": "runtime"}

IMAGES: tuple[ImageSpec, ...] = (
    ImageSpec("python", "coral/python", "3.11-bookworm", "testbed/images/python/Dockerfile",
              Context.DEBIAN_ROOTFS),
    ImageSpec("runtime", "coral/runtime", VERSION, "components/Dockerfile", Context.REPOSITORY,
              {"BASE": "python"}),
    ImageSpec("executor", "coral/executor", VERSION, "components/coral/executor/Dockerfile",
              Context.REPOSITORY, _RUNTIME_CHILD),
    ImageSpec("bag-player", "coral/bag-player", VERSION, "components/drivers/bag_player/Dockerfile",
              Context.REPOSITORY, _RUNTIME_CHILD),
    ImageSpec("examples-skillset", "coral/examples-skillset", VERSION,
              "components/skillsets/examples/Dockerfile", Context.REPOSITORY, _RUNTIME_CHILD),
    ImageSpec("slam-skillset", "coral/slam-skillset", VERSION, "components/skillsets/slam/Dockerfile",
              Context.REPOSITORY, _RUNTIME_CHILD),
    ImageSpec("snapshot-skillset", "coral/snapshot-skillset", VERSION,
              "components/skillsets/snapshot/Dockerfile", Context.REPOSITORY, _RUNTIME_CHILD),
    ImageSpec("operator", "coral-on-kubernetes/coral-operator", VERSION, "operator/Dockerfile",
              Context.REPOSITORY, {"BASE": "python"}),
    ImageSpec("kind-net", "coral/kind-net", VERSION, "testbed/images/kind-net/Dockerfile",
              Context.REPOSITORY, {"BASE": "python"}),
)

COMPONENTS = ("executor", "bag-player", "examples-skillset", "slam-skillset", "snapshot-skillset")
"""The images that run Coral components: all FROM runtime, as the non-root user coral."""
EXPORTING = ("bag-player", "examples-skillset", "slam-skillset", "snapshot-skillset")
"""The component images whose component exports a plugin manifest: their build writes the
`dev.coral.exports` label the operator's preflight reads (docs/preflight.md)."""


def by_name() -> dict[str, ImageSpec]:
    return {spec.name: spec for spec in IMAGES}


def with_parents(names: Iterable[str]) -> list[ImageSpec]:
    """The named images and every image they start FROM, parents before children.

    Raises:
        KeyError: an unknown name, with the known ones in the message.
    """
    known = by_name()
    wanted: set[str] = set()

    def visit(name: str) -> None:
        if name not in known:
            raise KeyError(f"no image named {name!r}; known: {', '.join(known)}")
        if name in wanted:
            return
        wanted.add(name)
        for parent in known[name].parents.values():
            visit(parent)

    for name in names:
        visit(name)
    # IMAGES lists parents before children, so its order is a valid build order.
    return [spec for spec in IMAGES if spec.name in wanted]
