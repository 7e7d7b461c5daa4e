"""The only module that runs buildah: build, inspect, push, pull and run images without a daemon.

Its storage lives in the project's cache folder, apart from any system-wide container storage.
RUN steps use chroot isolation and the host's network, which works as root without a daemon, user
namespaces or CAP_SYS_ADMIN tricks. Called by `building` and the image tests.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

STORAGE_DRIVER_ENV = "CORAL_IMAGE_STORAGE_DRIVER"
_QUIET_SECONDS = 20.0


class BuildahError(RuntimeError):
    """buildah is missing or a buildah command failed; the message has its output or log path."""


def overlay_works() -> bool:
    """Whether this kernel mounts overlayfs here (else the slower, larger vfs driver is used)."""
    with tempfile.TemporaryDirectory(prefix="coral-overlay-probe-") as scratch:
        root = Path(scratch)
        for name in ("lower", "upper", "work", "merged"):
            (root / name).mkdir()
        options = f"lowerdir={root / 'lower'},upperdir={root / 'upper'},workdir={root / 'work'}"
        mounted = subprocess.run(
            ["mount", "-t", "overlay", "overlay", "-o", options, str(root / "merged")],
            capture_output=True,
        )
        if mounted.returncode != 0:
            return False
        subprocess.run(["umount", str(root / "merged")], capture_output=True)
        return True


@dataclass(frozen=True)
class Buildah:
    """buildah bound to one storage folder and driver."""

    root: Path
    driver: str

    @classmethod
    def at(cls, folder: Path, driver: str) -> Buildah:
        if shutil.which("buildah") is None:
            raise BuildahError("buildah is not installed; run `sudo bash hack/setup-node-runtime.sh`")
        # Keyed by driver: one storage folder cannot switch drivers once it holds layers.
        return cls(root=folder / f"storage-{driver}", driver=driver)

    def _argv(self, *args: str) -> list[str]:
        return [
            "buildah",
            "--root", str(self.root / "root"),
            "--runroot", str(self.root / "run"),
            "--storage-driver", self.driver,
            *args,
        ]

    def _run(self, *args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
        done = subprocess.run(self._argv(*args), capture_output=True, text=True)
        if check and done.returncode != 0:
            raise BuildahError(f"buildah {args[0]} failed: {(done.stderr or done.stdout).strip()}")
        return done

    def inspect(self, reference: str) -> dict[str, Any] | None:
        """`buildah inspect` of a local image, None if the store does not have it."""
        done = self._run("inspect", "--type", "image", reference, check=False)
        if done.returncode != 0:
            return None
        data: dict[str, Any] = json.loads(done.stdout)
        return data

    def image_id(self, reference: str) -> str | None:
        data = self.inspect(reference)
        return None if data is None else str(data["FromImageID"])

    def labels(self, reference: str) -> dict[str, str]:
        data = self.inspect(reference)
        if data is None:
            return {}
        return dict(data["OCIv1"]["config"].get("Labels") or {})

    def config(self, reference: str) -> dict[str, Any]:
        """The OCI image config (`Entrypoint`, `Cmd`, `User`, `Env`, ...) of a local image."""
        data = self.inspect(reference)
        if data is None:
            raise BuildahError(f"no image {reference} in {self.root}")
        return dict(data["OCIv1"]["config"])

    def unpacked_size(self, reference: str) -> str:
        """The image's unpacked size as buildah prints it ("562 MB")."""
        done = self._run("images", "--json", reference)
        return str(json.loads(done.stdout)[0]["size"])

    def build(
        self,
        dockerfile: Path,
        context: Path,
        tag: str,
        build_args: Mapping[str, str],
        labels: Mapping[str, str],
        volumes: Sequence[str],
        log: Path,
        on_step: Callable[[str], None],
    ) -> str:
        """Builds `dockerfile` in `context` into the local image `tag`; returns its image ID.

        Every parent image must already be in the store (`--pull=never`): `building` brings them.
        Output goes to `log`; each "STEP n/m" line is passed to `on_step`, and so is the latest
        output line when nothing was passed for a while.
        """
        log.parent.mkdir(parents=True, exist_ok=True)
        iidfile = log.with_suffix(".iid")
        argv = self._argv(
            "bud",
            "--isolation", "chroot",
            "--network", "host",
            "--pull=never",
            "--iidfile", str(iidfile),
            "-f", str(dockerfile),
            "-t", tag,
        )
        for name, value in sorted(build_args.items()):
            argv += ["--build-arg", f"{name}={value}"]
        for name, value in sorted(labels.items()):
            argv += ["--label", f"{name}={value}"]
        for volume in volumes:
            argv += ["--volume", volume]
        argv.append(str(context))
        with log.open("w") as sink:
            child = subprocess.Popen(
                argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1
            )
            assert child.stdout is not None
            last_shown = time.monotonic()
            for line in child.stdout:
                sink.write(line)
                # Steps as they start, and during a long RUN step its latest line now and then.
                now = time.monotonic()
                if line.startswith("STEP ") or (line.strip() and now - last_shown > _QUIET_SECONDS):
                    on_step(line.strip()[:160])
                    last_shown = now
            code = child.wait()
        if code != 0:
            raise BuildahError(f"building {tag} from {dockerfile} failed (exit {code}); see {log}")
        return iidfile.read_text().strip().removeprefix("sha256:")

    def push(self, reference: str, destination: str) -> str:
        """Pushes a local image to `destination` (host:port/repo:tag over plain HTTP); returns the digest."""
        with tempfile.NamedTemporaryFile(prefix="coral-digest-") as digestfile:
            self._run("push", "--tls-verify=false", "--digestfile", digestfile.name,
                      reference, f"docker://{destination}")
            return Path(digestfile.name).read_text().strip()

    def save(self, reference: str, archive: Path, name: str) -> None:
        """Writes a local image as a `docker save` archive at `archive`, tagged `name` inside."""
        archive.unlink(missing_ok=True)
        self._run("push", "--quiet", reference, f"docker-archive:{archive}:{name}")

    def pull(self, source: str, tag: str) -> str:
        """Pulls `source` (host:port/repo:tag) into the store, tags it `tag`; returns its image ID."""
        done = self._run("pull", "--tls-verify=false", "--quiet", f"docker://{source}")
        image_id = done.stdout.strip().splitlines()[-1]
        self._run("tag", image_id, tag)
        # Only the local name stays: the registry's address differs from session to session.
        self._run("rmi", source)
        return image_id

    def remove(self, reference: str) -> None:
        """Untags and removes a local image; layers other images use stay."""
        self._run("rmi", reference)

    def prune_dangling(self) -> None:
        """Removes images no tag names any more (earlier builds), unless a container uses them."""
        self._run("rmi", "--prune", check=False)

    def run(
        self, reference: str, argv: Sequence[str], timeout: float = 120
    ) -> subprocess.CompletedProcess[str]:
        """Runs `argv` in a fresh working container of a local image (as the image's user)."""
        created = self._run("from", "--pull=never", "--quiet", reference)
        container = created.stdout.strip().splitlines()[-1]
        try:
            return subprocess.run(
                self._argv("run", "--isolation", "chroot", container, "--", *argv),
                capture_output=True, text=True, timeout=timeout,
            )
        finally:
            self._run("rm", container, check=False)
