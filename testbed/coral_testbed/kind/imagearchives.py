"""Single-purpose images written straight to `docker save` archives, for preloading into a node image.

The control-plane images kubeadm expects (kube-apiserver, etcd, coredns, pause, ...) are one static
binary each, so each is a layer holding that binary and a config naming its entrypoint; kube-proxy
adds a Debian layer with iptables and conntrack beneath it. containerd imports the archive under the
name in `RepoTags`. No builder is involved: the project's images still come from buildah
(`coral_testbed.images`). Called by `nodeimage`.
"""

from __future__ import annotations

import hashlib
import io
import json
import tarfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

PATH = "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"


@dataclass(frozen=True)
class ArchiveImage:
    """One image: its full name, layers base first, and its entrypoint."""

    reference: str
    files: dict[str, Path]
    """Path inside the image -> file on the host, all in one top layer (mode 0755)."""
    base_layers: Sequence[Path] = ()
    """Ready-made layer tarballs under the files' layer (a Debian root filesystem, say)."""
    entrypoint: Sequence[str] = ()
    env: Sequence[str] = field(default_factory=lambda: (f"PATH={PATH}",))
    stop_signal: str | None = None


def _files_layer(files: dict[str, Path]) -> bytes:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w", format=tarfile.PAX_FORMAT) as layer:
        folders = sorted(
            {parent for inside in files for parent in Path(inside.lstrip("/")).parents} - {Path(".")}
        )
        for folder in folders:
            info = tarfile.TarInfo(str(folder))
            info.type, info.mode = tarfile.DIRTYPE, 0o755
            layer.addfile(info)
        for inside, source in sorted(files.items()):
            info = layer.gettarinfo(str(source), arcname=inside.lstrip("/"))
            info.mode, info.uid, info.gid, info.uname, info.gname, info.mtime = 0o755, 0, 0, "", "", 0
            with source.open("rb") as content:
                layer.addfile(info, content)
    return buffer.getvalue()


def _sha256_of_file(path: Path) -> str:
    with path.open("rb") as content:
        return hashlib.file_digest(content, "sha256").hexdigest()


def write(image: ArchiveImage, archive: Path) -> None:
    """Writes `image` as a `docker save` archive at `archive`."""
    top = _files_layer(image.files)
    top_id = hashlib.sha256(top).hexdigest()
    base_ids = [_sha256_of_file(layer) for layer in image.base_layers]
    config = {
        "architecture": "amd64",
        "os": "linux",
        "config": {
            "Env": list(image.env),
            "Entrypoint": list(image.entrypoint) or None,
            "StopSignal": image.stop_signal,
        },
        "rootfs": {"type": "layers", "diff_ids": [f"sha256:{d}" for d in [*base_ids, top_id]]},
    }
    config_bytes = json.dumps(config, sort_keys=True).encode()
    config_name = f"{hashlib.sha256(config_bytes).hexdigest()}.json"
    layer_names = [f"{d}/layer.tar" for d in [*base_ids, top_id]]
    manifest = [{"Config": config_name, "RepoTags": [image.reference], "Layers": layer_names}]
    archive.parent.mkdir(parents=True, exist_ok=True)
    with tarfile.open(archive, "w") as out:
        for name, source in zip(layer_names, image.base_layers, strict=False):
            out.add(str(source), arcname=name)
        _add_bytes(out, layer_names[-1], top)
        _add_bytes(out, config_name, config_bytes)
        _add_bytes(out, "manifest.json", json.dumps(manifest).encode())


def _add_bytes(out: tarfile.TarFile, name: str, data: bytes) -> None:
    info = tarfile.TarInfo(name)
    info.size = len(data)
    out.addfile(info, io.BytesIO(data))
