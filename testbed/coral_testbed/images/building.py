"""Builds the catalog's images in dependency order, skipping unchanged ones, and pushes them.

For each image: stage its context, fingerprint its inputs (`fingerprints`), reuse the local image
when its fingerprint label matches, else take it from the registry when the registry has it, else
build it with buildah; then push it unless the registry already holds that exact image. Builds on
one machine are serialized by a lock file, so parallel test sessions share one cache. Called by
`coral images build`, the test fixtures and the demo.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass
from pathlib import Path

from coral_core.image_exports import EXPORTS_LABEL

from coral_testbed.cluster import binaries
from coral_testbed.images import buildah, catalog, fingerprints, registry, rootfs

Progress = Callable[[str], None]
HOST_CA_BUNDLE = Path("/etc/ssl/certs/ca-certificates.crt")


class ImageBuildError(RuntimeError):
    """An image could not be staged, built, pulled or pushed; the message says which and why."""


def say(line: str) -> None:
    """Default progress sink: one line on stderr, flushed."""
    print(f"==> [images] {line}", file=sys.stderr, flush=True)


@dataclass(frozen=True)
class Built:
    """One image after `build`: where it is and whether this run had to build it."""

    spec: catalog.ImageSpec
    image_id: str
    fingerprint: str
    outcome: str
    """"built", "cached" (local image matched) or "pulled" (taken from the registry)."""
    digest: str
    """Manifest digest in the registry, empty when nothing was pushed."""
    seconds: float

    @property
    def local_reference(self) -> str:
        return local_reference(self.spec)

    def registry_reference(self, address: str) -> str:
        return f"{address}/{self.spec.reference}"


def local_reference(spec: catalog.ImageSpec) -> str:
    return f"localhost/{spec.reference}"


def images_dir() -> Path:
    return binaries.cache_root() / "images"


def registry_storage() -> Path:
    """The registry storage of this checkout.

    Every checkout pushes the same tags (`coral/executor:0.1.0`), so two checkouts of different
    trees sharing one storage would hand each other's robots the wrong images. One storage per
    checkout keeps a tag meaning this tree's image; the local build store stays shared.
    """
    checkout = str(find_repository_root().resolve()).encode()
    return binaries.cache_root() / "registry" / hashlib.sha256(checkout).hexdigest()[:12]


def registry_state_dir() -> Path:
    """Where `registry.up` records the registries it keeps running (shared by every command)."""
    return images_dir() / "registries"


def find_repository_root() -> Path:
    """The repository this package was installed from (editable), holding the Dockerfiles."""
    for folder in Path(__file__).resolve().parents:
        if (folder / "components" / "Dockerfile").is_file() and (folder / "pyproject.toml").is_file():
            return folder
    raise ImageBuildError(
        "the repository's Dockerfiles are not next to this installation; "
        "install the project in editable mode (`make venv`) from a checkout"
    )


def builder() -> buildah.Buildah:
    driver = os.environ.get(buildah.STORAGE_DRIVER_ENV) or ("overlay" if buildah.overlay_works() else "vfs")
    return buildah.Buildah.at(images_dir(), driver)


def _context(spec: catalog.ImageSpec, root: Path, cache: Path, progress: Progress) -> Path:
    if spec.context is catalog.Context.REPOSITORY:
        return root
    return rootfs.ensure(cache, progress)


def _volumes(spec: catalog.ImageSpec) -> list[str]:
    # RUN steps reach PyPI through the host's network, so they trust what the host trusts (a
    # site CA, say). The bundle is mounted over the base's own for the build only; the image
    # keeps Debian's bundle.
    if spec.context is catalog.Context.REPOSITORY and HOST_CA_BUNDLE.is_file():
        return [f"{HOST_CA_BUNDLE}:{HOST_CA_BUNDLE}:ro"]
    return []


@contextmanager
def exclusive(progress: Progress = say) -> Iterator[None]:
    """Holds the machine's image-build lock: no other build reads or changes the store meanwhile."""
    cache = images_dir()
    cache.mkdir(parents=True, exist_ok=True)
    with (cache / "build.lock").open("w") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            progress("another build holds the image cache; waiting for it")
            fcntl.flock(lock, fcntl.LOCK_EX)
        yield


def is_current(spec: catalog.ImageSpec, labels: dict[str, str], fingerprint: str) -> bool:
    """Whether an image with `labels` is what building `spec` now would give: same inputs, and the
    exports declaration where the image's component makes one (images built before the label
    existed lack it and are built again)."""
    declares = spec.name not in catalog.EXPORTING or EXPORTS_LABEL in labels
    return labels.get(fingerprints.LABEL) == fingerprint and declares


def _registry_is_current(address: str, spec: catalog.ImageSpec, fingerprint: str) -> bool:
    found = registry.manifest(address, spec.repository, spec.tag)
    if found is None:
        return False
    config = registry.image_config(address, spec.repository, found.config_digest)
    return is_current(spec, (config.get("config") or {}).get("Labels") or {}, fingerprint)


def _exports_labels(
    tool: buildah.Buildah, spec: catalog.ImageSpec, parent_ids: dict[str, str]
) -> dict[str, str]:
    """The `dev.coral.exports` label of a component image, from the manifest its component exports,
    read in the runtime image it starts FROM (which holds every component; the image adds none)."""
    if spec.name not in catalog.EXPORTING:
        return {}
    done = tool.run(parent_ids["RUNTIME"], ["coral", "verify", spec.repository, "--print-label"])
    if done.returncode != 0 or not done.stdout.strip():
        raise ImageBuildError(
            f"{spec.name}: `coral verify {spec.repository} --print-label` in the runtime image failed "
            f"(exit {done.returncode}): {(done.stderr or done.stdout).strip()[-2000:]}"
        )
    return {EXPORTS_LABEL: done.stdout.strip().splitlines()[-1]}


def _push(
    tool: buildah.Buildah, address: str, spec: catalog.ImageSpec, image_id: str, progress: Progress
) -> str:
    found = registry.manifest(address, spec.repository, spec.tag)
    if found is not None and found.config_digest == f"sha256:{image_id}":
        return found.digest
    progress(f"{spec.name}: pushing to {address}/{spec.reference}")
    try:
        return tool.push(local_reference(spec), f"{address}/{spec.reference}")
    except buildah.BuildahError as error:
        raise ImageBuildError(f"{spec.name}: push to {address} failed: {error}") from error


def _build_one(
    spec: catalog.ImageSpec,
    done: dict[str, Built],
    tool: buildah.Buildah,
    root: Path,
    cache: Path,
    address: str | None,
    progress: Progress,
) -> Built:
    started = time.monotonic()
    context = _context(spec, root, cache, progress)
    dockerfile = root / spec.dockerfile
    parent_ids = {arg: done[parent].image_id for arg, parent in spec.parents.items()}
    fingerprint = fingerprints.compute(dockerfile, context, build_args={}, parent_ids=parent_ids)
    local = local_reference(spec)
    if is_current(spec, tool.labels(local), fingerprint):
        outcome = "cached"
        image_id = tool.image_id(local) or ""
    elif address is not None and _registry_is_current(address, spec, fingerprint):
        outcome = "pulled"
        progress(f"{spec.name}: unchanged, taking it from {address}")
        image_id = tool.pull(f"{address}/{spec.reference}", local)
    else:
        outcome = "built"
        progress(f"{spec.name}: building {spec.dockerfile}")
        try:
            image_id = tool.build(
                dockerfile=dockerfile,
                context=context,
                tag=local,
                # Parents by image ID: exactly the image the fingerprint covered.
                build_args=parent_ids,
                labels={fingerprints.LABEL: fingerprint, **_exports_labels(tool, spec, parent_ids)},
                volumes=_volumes(spec),
                log=cache / "logs" / f"{spec.name}.log",
                on_step=lambda step: progress(f"{spec.name}: {step}"),
            )
        except buildah.BuildahError as error:
            raise ImageBuildError(str(error)) from error
    digest = _push(tool, address, spec, image_id, progress) if address is not None else ""
    seconds = time.monotonic() - started
    progress(f"{spec.name}: {outcome} {spec.reference} ({image_id[:12]}) in {seconds:.1f} s")
    return Built(spec, image_id, fingerprint, outcome, digest, seconds)


def build(
    names: Iterable[str] | None = None,
    registry_address: str | None = None,
    progress: Progress = say,
    lock_held: bool = False,
) -> dict[str, Built]:
    """Builds the named images (all when None) and the images they start FROM.

    Args:
        names: catalog names (`runtime`, `executor`, ...); their parents are built first.
        registry_address: HOST:PORT of a running registry to push to (and to take unchanged
            images from when the local store lost them); None builds locally only.
        progress: receives one line per step worth showing.
        lock_held: the caller already holds `exclusive()` (else this call takes it).

    Returns:
        Every image handled, by name, parents first.

    Raises:
        ImageBuildError, rootfs.RootfsError, buildah.BuildahError: with the failing image and log.
    """
    specs = catalog.with_parents(names if names is not None else [s.name for s in catalog.IMAGES])
    if os.geteuid() != 0:
        raise ImageBuildError("building images needs root (buildah's chroot isolation and mounts)")
    root = find_repository_root()
    cache = images_dir()
    tool = builder()
    done: dict[str, Built] = {}
    with nullcontext() if lock_held else exclusive(progress):
        for spec in specs:
            done[spec.name] = _build_one(spec, done, tool, root, cache, registry_address, progress)
        if any(built.outcome != "cached" for built in done.values()):
            # Each rebuild leaves the previous image untagged: hundreds of MB a time otherwise.
            tool.prune_dangling()
    return done


def publish(address: str, names: Iterable[str] | None = None, progress: Progress = say) -> dict[str, Built]:
    """Keeps a registry serving on `address` (starting one if none is) and builds the images into it.

    The registry outlives this call; `registry.down(registry_state_dir(), address)` stops it.
    """
    if not registry.is_serving(address):
        registry.up(address, registry_storage(), registry_state_dir())
        progress(f"registry serving on {address}")
    return build(names, registry_address=address, progress=progress)
