"""Where the pinned control-plane binaries live, and a clear error when they do not exist yet.

`hack/build-control-plane.sh` builds them into a cache folder keyed by the versions below; the
local control plane, the test fixture and the demo find them here. The versions must match the
script's defaults (a test compares them).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

KUBE_VERSION = "v1.34.4"
ETCD_VERSION = "v3.6.4"
KWOK_VERSION = "v0.7.0"
HELM_VERSION = "v3.19.0"

REQUIRED = ("etcd", "kube-apiserver", "kube-controller-manager", "kube-scheduler", "kubectl", "kwok")

# Overrides the cache lookup, e.g. for binaries installed elsewhere at the same versions.
BIN_DIR_ENV = "CORAL_CONTROL_PLANE_BIN"


class BinariesMissing(RuntimeError):
    """The control-plane binaries have not been built yet."""


def cache_root() -> Path:
    return Path(os.environ.get("CORAL_CACHE_DIR", Path.home() / ".cache" / "coral-on-kubernetes"))


def cache_key() -> str:
    return f"kube-{KUBE_VERSION}_etcd-{ETCD_VERSION}_kwok-{KWOK_VERSION}_helm-{HELM_VERSION}"


def default_bin_dir() -> Path:
    return cache_root() / "control-plane" / cache_key() / "bin"


def missing_in(bin_dir: Path, names: tuple[str, ...] = REQUIRED) -> list[str]:
    return [name for name in names if not os.access(bin_dir / name, os.X_OK)]


def find_bin_dir(names: tuple[str, ...] = REQUIRED) -> Path:
    """Returns the folder holding the pinned binaries.

    Raises:
        BinariesMissing: naming the folder, the missing binaries and the command that builds them.
    """
    override = os.environ.get(BIN_DIR_ENV)
    bin_dir = Path(override) if override else default_bin_dir()
    missing = missing_in(bin_dir, names)
    if missing:
        source = f"${BIN_DIR_ENV}" if override else "the build cache"
        raise BinariesMissing(
            f"{', '.join(missing)} not found in {bin_dir} ({source}); "
            "build them with `make control-plane` (runs hack/build-control-plane.sh)"
        )
    return bin_dir


def optional_bin_dir(names: tuple[str, ...] = REQUIRED) -> Path | None:
    """The pinned bin folder if it is complete, else None (external clusters may live without it)."""
    try:
        return find_bin_dir(names)
    except BinariesMissing:
        return None


def find_kubectl(bin_dir: Path | None) -> str:
    """The pinned kubectl when built, else the one on PATH."""
    if bin_dir is not None and os.access(bin_dir / "kubectl", os.X_OK):
        return str(bin_dir / "kubectl")
    pinned = optional_bin_dir(("kubectl",))
    if pinned is not None:
        return str(pinned / "kubectl")
    found = shutil.which("kubectl")
    if found is None:
        raise BinariesMissing("kubectl is neither built (`make control-plane`) nor on PATH")
    return found
