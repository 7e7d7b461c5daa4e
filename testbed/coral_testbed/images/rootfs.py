"""The Debian bookworm root filesystem under the `python` base image, made by mmdebstrap.

Bookworm's python3.11 matches the cp311 ROS 2 wheels on PyPI. The `essential` variant plus the few
packages Python needs (and libstdc++, which manylinux wheels expect from the system) keeps the
base about 110 MB; documentation, manuals and translations are left out. The tarball is cached by
its recipe, so a machine bootstraps once (about 90 s); called by `building`.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
from collections.abc import Callable
from pathlib import Path

SUITE = "bookworm"
PACKAGES = ("python3.11", "python3.11-venv", "ca-certificates", "passwd", "libstdc++6")
MIRROR_ENV = "CORAL_DEBIAN_MIRROR"
SECURITY_MIRROR_ENV = "CORAL_DEBIAN_SECURITY_MIRROR"
_MERGED_USR_HOOK = Path("/usr/share/mmdebstrap/hooks/merged-usr")
_DPKG_OPTIONS = (
    "path-exclude=/usr/share/man/*",
    "path-exclude=/usr/share/info/*",
    "path-exclude=/usr/share/locale/*",
    "path-exclude=/usr/share/doc/*",
    "path-include=/usr/share/doc/*/copyright",
)


class RootfsError(RuntimeError):
    """mmdebstrap is missing or failed; the message says which and where its log is."""


def _sources() -> list[str]:
    mirror = os.environ.get(MIRROR_ENV, "http://deb.debian.org/debian")
    security = os.environ.get(SECURITY_MIRROR_ENV, "http://deb.debian.org/debian-security")
    return [
        f"deb {mirror} {SUITE} main",
        f"deb {mirror} {SUITE}-updates main",
        f"deb {security} {SUITE}-security main",
    ]


def command(output: Path) -> list[str]:
    """The mmdebstrap command line that writes the root filesystem to `output` (a .tar)."""
    argv = ["mmdebstrap", "--variant=essential", f"--include={','.join(PACKAGES)}"]
    # Bookworm's merged /usr without the usrmerge package (which would pull in perl).
    argv.append(f"--hook-dir={_MERGED_USR_HOOK}")
    argv += [f"--dpkgopt={option}" for option in _DPKG_OPTIONS]
    return [*argv, SUITE, str(output), *_sources()]


def recipe_key() -> str:
    """Names the cached tarball: changes when the packages, mirrors or options change."""
    text = json.dumps(command(Path("rootfs.tar")))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def ensure(cache_dir: Path, progress: Callable[[str], None]) -> Path:
    """The folder holding rootfs.tar, bootstrapping it first if this recipe was never built.

    Raises:
        RootfsError: mmdebstrap is not installed or failed.
    """
    folder = cache_dir / "rootfs" / recipe_key()
    tarball = folder / "rootfs.tar"
    if tarball.is_file():
        return folder
    if not _MERGED_USR_HOOK.is_dir():
        raise RootfsError("mmdebstrap is not installed; run `sudo bash hack/setup-node-runtime.sh`")
    folder.mkdir(parents=True, exist_ok=True)
    partial = folder / "rootfs.tar.partial.tar"
    log = folder / "mmdebstrap.log"
    progress(f"bootstrapping Debian {SUITE} with {', '.join(PACKAGES)} (first run: about 90 s)")
    with log.open("w") as sink:
        child = subprocess.Popen(
            command(partial), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1
        )
        assert child.stdout is not None
        for line in child.stdout:
            sink.write(line)
            # mmdebstrap's "I: ..." lines mark its phases (download, extract, install, tar).
            if line.startswith("I: ") and "..." in line:
                progress(f"  {line[3:].strip()}")
        code = child.wait()
    if code != 0:
        partial.unlink(missing_ok=True)
        raise RootfsError(f"mmdebstrap failed with exit code {code}; see {log}")
    partial.rename(tarball)
    return folder
