"""Content hashes of exported files: computed at export, checked before an executor imports code.

Called by `exporting` and `discovery`.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from coral.plugins import manifest as manifests

# Only code is hashed: the manifest, the `ready` marker and its staging file live beside it.
HASHED_FOLDERS = {manifests.BEHAVIORS_DIR, manifests.INTERFACES_DIR}


def sha256_file(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 16), b""):
            digest.update(block)
    return digest.hexdigest()


def hash_tree(root: Path) -> dict[str, str]:
    """Relative POSIX path -> sha256 for every file under `root`'s code folders, skipping caches."""
    hashes: dict[str, str] = {}
    for path in sorted(root.rglob("*")):
        if not path.is_file() or "__pycache__" in path.parts:
            continue
        relative_path = path.relative_to(root)
        if relative_path.parts[0] not in HASHED_FOLDERS:
            continue
        relative = relative_path.as_posix()
        hashes[relative] = sha256_file(path)
    return hashes


def verify(root: Path, expected: dict[str, str]) -> str | None:
    """Why the files under `root` do not match `expected`, or None when every hash matches."""
    actual = hash_tree(root)
    for relative, digest in sorted(expected.items()):
        if relative not in actual:
            return f"file {relative} listed in the manifest is missing"
        if actual[relative] != digest:
            return f"file {relative} does not match its sha256 in the manifest (corrupt or modified)"
    unlisted = sorted(set(actual) - set(expected))
    if unlisted:
        return f"file {unlisted[0]} is not listed in the manifest"
    return None
