"""An image's fingerprint: a hash of everything its build reads, so an unchanged tree rebuilds nothing.

Covers the Dockerfile, the context files its COPY/ADD instructions can see (after .dockerignore),
the build arguments, and the IDs of the images it starts FROM. Called by `building`, which stores
the fingerprint as a label on the image and skips the build when the label already matches.
"""

from __future__ import annotations

import fnmatch
import hashlib
import os
from collections.abc import Iterator, Mapping
from pathlib import Path

from coral_testbed.images import dockerfiles, dockerignore

LABEL = "dev.coral.build.fingerprint"
# Bumped when the recipe changes in a way the inputs below do not show.
_SCHEME = "coral-image-fingerprint/1"


def _walk(context: Path, rules: list[dockerignore.Rule]) -> Iterator[str]:
    for folder, subfolders, files in os.walk(context):
        relative = Path(folder).relative_to(context).as_posix()
        prefix = "" if relative == "." else f"{relative}/"
        subfolders[:] = sorted(s for s in subfolders if not dockerignore.can_prune(rules, prefix + s))
        for name in sorted(files):
            path = prefix + name
            if not dockerignore.is_excluded(rules, path):
                yield path


def context_files(dockerfile: dockerfiles.Dockerfile, context: Path) -> list[str]:
    """The context-relative paths the build can copy, sorted; all visible files if unknowable."""
    rules = dockerignore.read(context)
    visible = list(_walk(context, rules))
    sources = dockerfile.context_sources()
    if sources is None:
        return visible
    used: set[str] = set()
    for source in sources:
        cleaned = os.path.normpath(source).lstrip("/")
        if cleaned == ".":
            return visible
        for path in visible:
            if path == cleaned or path.startswith(cleaned + "/") or fnmatch.fnmatchcase(path, cleaned):
                used.add(path)
    return sorted(used)


def _file_digest(path: Path) -> str:
    with path.open("rb") as stream:
        return hashlib.file_digest(stream, "sha256").hexdigest()


def compute(
    dockerfile_path: Path,
    context: Path,
    build_args: Mapping[str, str],
    parent_ids: Mapping[str, str],
) -> str:
    """The fingerprint (hex sha256) of one build.

    Args:
        dockerfile_path: the Dockerfile.
        context: the build context folder.
        build_args: build arguments whose values are plain text.
        parent_ids: build arguments naming images, mapped to those images' IDs, so a rebuilt
            parent changes the child's fingerprint while the parent's address does not.
    """
    dockerfile = dockerfiles.read(dockerfile_path)
    digest = hashlib.sha256()

    def add(*parts: str) -> None:
        for part in parts:
            digest.update(part.encode())
            digest.update(b"\0")

    add(_SCHEME, "dockerfile", hashlib.sha256(dockerfile_path.read_bytes()).hexdigest())
    for name in sorted(build_args):
        add("arg", name, build_args[name])
    for name in sorted(parent_ids):
        add("parent", name, parent_ids[name])
    for relative in context_files(dockerfile, context):
        path = context / relative
        executable = "x" if os.access(path, os.X_OK) else "-"
        target = os.readlink(path) if path.is_symlink() else _file_digest(path)
        add("file", relative, executable, target)
    return digest.hexdigest()
