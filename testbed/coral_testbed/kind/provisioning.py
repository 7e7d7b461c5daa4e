"""What a kind cluster needs on this machine, installed where missing and cached: one line per step.

1. a Docker engine from Debian (`hack/setup-docker.sh`), started as the project's own dockerd
   (`engine`: its own socket, leaves the host's forwarding and firewall alone);
2. kind and the node binaries from Go modules (`hack/build-kind-tools.sh`, cached by version);
3. the control-plane binaries (`hack/build-control-plane.sh`, cached by version);
4. the host's inotify limits, raised where too low for several nodes (`hostlimits`);
5. the node image (`nodeimage`: pulled where possible, else built here, cached by content).

Installers' output goes to one log whose path is printed. Called by `coral dev-cluster setup`
(`make kind`) and before every cluster is created.
"""

from __future__ import annotations

import contextlib
import functools
import os
import shutil
import subprocess
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from coral_testbed.cluster import binaries
from coral_testbed.kind import engine, hostlimits, nodeimage


class SetupError(RuntimeError):
    """A setup step failed; the message names it and its log."""


@dataclass(frozen=True)
class Ready:
    engine: engine.Engine
    node_image: str


@contextlib.contextmanager
def _step(progress: Callable[[str], None], name: str) -> Iterator[None]:
    """Prints the step, then how long it took."""
    began = time.monotonic()
    progress(name)
    yield
    progress(f"  done in {time.monotonic() - began:.1f} s")


def unsupported_reason() -> str | None:
    """Why kind clusters cannot be made on this machine, or None when they can."""
    if os.geteuid() != 0:
        return "kind clusters need root here (the project's dockerd, the node image build)"
    for tool, how in (
        ("dockerd", "sudo bash hack/setup-docker.sh"),
        ("go", "a Go toolchain"),
        ("buildah", "sudo bash hack/setup-node-runtime.sh"),
        ("mmdebstrap", "sudo bash hack/setup-node-runtime.sh"),
    ):
        if shutil.which(tool) is None:
            return f"kind clusters need {tool} ({how})"
    return None


def log_path() -> Path:
    return binaries.cache_root() / "kind" / "setup.log"


def _script(name: str, log: Path, step: str) -> str:
    script = nodeimage.repository_root() / "hack" / name
    with log.open("a") as sink:
        sink.write(f"$ bash hack/{name}\n")
        sink.flush()
        done = subprocess.run(["bash", str(script)], stdout=subprocess.PIPE, stderr=sink, text=True)
    if done.returncode != 0:
        raise SetupError(f"{step} failed (exit {done.returncode}); see {log}")
    return done.stdout


def ensure(progress: Callable[[str], None]) -> Ready:
    """Runs every step (each a no-op when done before) and returns the engine and node image to use.

    The engine is left running: `engine.stop()` (or `coral dev-cluster down`) stops it.

    Raises:
        SetupError, engine.EngineError, noderootfs.NodeImageError: naming the step and the log.
    """
    log = log_path()
    log.parent.mkdir(parents=True, exist_ok=True)
    progress(f"kind setup; installers' output goes to {log}")
    timed = functools.partial(_step, progress)
    with timed("Docker engine (Debian's docker.io, where dockerd is missing)"):
        _script("setup-docker.sh", log, "installing docker.io")
    with timed("control-plane binaries (kubelet, kubectl, kube-apiserver, ...; cached by version)"):
        _script("build-control-plane.sh", log, "hack/build-control-plane.sh")
    with timed("the host's inotify limits (kind's nodes each take some)"):
        for line in hostlimits.ensure():
            progress(f"  {line}")
    with timed("the project's dockerd"):
        node_engine = engine.start(lambda line: progress(f"  {line}"))
    with timed("node image"):
        image = nodeimage.ensure(node_engine, lambda line: progress(f"  {line}"), log)
    return Ready(node_engine, image)
