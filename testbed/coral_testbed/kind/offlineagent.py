"""The robot's offline agent on kind robots, installed as docs/offline.md tells a robot's owner.

On each robot's node (after it joined, so the kubelet's kubeconfig exists): a virtual environment
at `/opt/coral-offline-agent` on the node's own Python (the node image carries Debian's python3),
holding the agent and what it imports; the two systemd units of `deploy/robot/`; the boot unit
enabled (it runs at every boot, after containerd and before the kubelet) and the watch unit
enabled and started. The node has no network but the cluster's, so the environment's packages are
copied from this installation rather than downloaded: the agent's own packages (`coral_core`, and
`coral.offline` alone of the robot side) and the distributions `kubernetes` and `click` need.
Called by `clusters.create`.
"""

from __future__ import annotations

import concurrent.futures
import importlib.metadata
import io
import tarfile
import tempfile
from collections.abc import Iterator
from pathlib import Path

import coral
import coral_core
from packaging.requirements import Requirement

from coral_testbed.kind import engine

PREFIX = "/opt/coral-offline-agent"
"""Where the units of `deploy/robot/` expect the agent's environment."""
UNITS = ("coral-offline-boot.service", "coral-offline-agent.service")
STATIC_POD_DIR = "/etc/kubernetes/manifests"
"""kubeadm's `staticPodPath`, the units' default: where a kind robot's agent writes static pods."""
DISTRIBUTIONS = ("kubernetes", "click")
"""What the agent imports besides the standard library and the project's own packages."""


def units_dir() -> Path:
    for folder in Path(__file__).resolve().parents:
        candidate = folder / "deploy" / "robot"
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError("deploy/robot/ is not next to this installation (install with `make venv`)")


def _distributions(roots: tuple[str, ...]) -> list[importlib.metadata.Distribution]:
    """`roots` and everything they require (extras left out), as installed here."""
    found: dict[str, importlib.metadata.Distribution] = {}
    pending = list(roots)
    while pending:
        dist = importlib.metadata.distribution(pending.pop())
        key = dist.metadata["Name"].lower().replace("_", "-")
        if key in found:
            continue
        found[key] = dist
        for text in dist.requires or []:
            requirement = Requirement(text)
            if requirement.marker is None or requirement.marker.evaluate({"extra": ""}):
                pending.append(requirement.name)
    return [found[key] for key in sorted(found)]


def _package_files(package: Path, only: tuple[str, ...] = ()) -> Iterator[tuple[Path, str]]:
    """(file, its path in site-packages) for an import package's source folder."""
    for path in sorted(package.rglob("*")):
        inside = path.relative_to(package)
        if not path.is_file() or "__pycache__" in inside.parts or path.suffix == ".pyc":
            continue
        if only and inside.parts[0] not in only:
            continue
        yield path, f"{package.name}/{inside}"


def site_packages() -> bytes:
    """A tar of the agent's site-packages: the distributions' installed files and the agent's own
    packages from their source folders."""
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w") as tar:
        for dist in _distributions(DISTRIBUTIONS):
            for file in dist.files or []:
                # Scripts land outside site-packages ("../../../bin/..."): the agent needs none.
                if file.parts[0] == ".." or file.suffix == ".pyc":
                    continue
                tar.add(str(dist.locate_file(file)), arcname=str(file), recursive=False)
        core = Path(coral_core.__file__).parent
        for path, name in _package_files(core):
            tar.add(str(path), arcname=f"coral_core/{name.partition('/')[2]}", recursive=False)
        robot_side = Path(coral.__file__).parent
        for path, name in _package_files(robot_side, only=("__init__.py", "offline")):
            tar.add(str(path), arcname=f"coral/{name.partition('/')[2]}", recursive=False)
    return buffer.getvalue()


def _units() -> bytes:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w") as tar:
        for unit in UNITS:
            tar.add(str(units_dir() / unit), arcname=unit, recursive=False)
    return buffer.getvalue()


def install(node_engine: engine.Engine, nodes: list[str]) -> None:
    """Installs the agent on `nodes` (node containers of robots that joined) and starts it, on
    every node at once: each takes seconds of `docker cp` and `docker exec`, and a robot's install
    does not wait on another's."""
    with tempfile.TemporaryDirectory() as folder:
        packages, units = Path(folder) / "site-packages.tar", Path(folder) / "units.tar"
        packages.write_bytes(site_packages())
        units.write_bytes(_units())
        with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, len(nodes))) as pool:
            # list() so that a node's failure is raised here, naming its docker command.
            list(pool.map(lambda node: _install_on(node_engine, node, packages, units), nodes))


def _install_on(node_engine: engine.Engine, node: str, packages: Path, units: Path) -> None:
    node_engine.docker("exec", node, "python3", "-m", "venv", "--without-pip", PREFIX)
    purelib = node_engine.docker(
        "exec",
        node,
        f"{PREFIX}/bin/python",
        "-c",
        "import sysconfig; print(sysconfig.get_path('purelib'))",
    ).stdout.strip()
    for archive, target in ((packages, purelib), (units, "/etc/systemd/system")):
        # Into the node's own disk: docker cp does not see the tmpfs kind mounts on /tmp.
        copied = f"{PREFIX}/{archive.name}"
        node_engine.docker("cp", str(archive), f"{node}:{copied}")
        node_engine.docker("exec", node, "tar", "-x", "-f", copied, "-C", target)
        node_engine.docker("exec", node, "rm", copied)
    node_engine.docker("exec", node, "systemctl", "daemon-reload")
    node_engine.docker("exec", node, "systemctl", "enable", UNITS[0])
    node_engine.docker("exec", node, "systemctl", "enable", "--now", UNITS[1])
