"""The busybox test image, made here and loaded into nodes without a registry.

`TEST_IMAGE` is one layer holding Debian's busybox-static (sh, sleep, wget, httpd...), packed as a
reproducible OCI archive stored under its content digest; the kind tests load it into every node
with `kind load image-archive` for their plain pods.
"""

from __future__ import annotations

import gzip
import hashlib
import io
import json
import tarfile
from pathlib import Path

TEST_IMAGE = "coral.local/busybox:local"
BUSYBOX = Path("/bin/busybox")

# The default command sleeps until stopped: PID 1 ignores signals it has no handler for, so it
# traps them to stop at once.
_PAUSE = ["/bin/sh", "-c", "trap 'exit 0' TERM INT; while :; do sleep 3600 & wait $!; done"]
_APPLETS = (
    "sh",
    "sleep",
    "cat",
    "echo",
    "ls",
    "mkdir",
    "wget",
    "ssl_client",
    "nc",
    "timeout",
    "httpd",
    "touch",
    "test",
    "env",
    "id",
    "ip",
    "ps",
    "hostname",
    "true",
    "false",
)


class ImageError(RuntimeError):
    """The image could not be made; the message says why."""


def _add(layer: tarfile.TarFile, info: tarfile.TarInfo, data: bytes | None = None) -> None:
    info.mtime, info.uid, info.gid, info.uname, info.gname = 0, 0, 0, "", ""
    layer.addfile(info, io.BytesIO(data) if data is not None else None)


def _layer(busybox: bytes) -> bytes:
    out = io.BytesIO()
    with tarfile.open(fileobj=out, mode="w", format=tarfile.PAX_FORMAT) as layer:
        for folder in ("bin", "tmp", "etc", "proc", "sys", "dev"):
            info = tarfile.TarInfo(folder)
            info.type, info.mode = tarfile.DIRTYPE, 0o1777 if folder == "tmp" else 0o755
            _add(layer, info)
        info = tarfile.TarInfo("bin/busybox")
        info.size, info.mode = len(busybox), 0o755
        _add(layer, info, busybox)
        for applet in _APPLETS:
            link = tarfile.TarInfo(f"bin/{applet}")
            link.type, link.linkname, link.mode = tarfile.SYMTYPE, "busybox", 0o777
            _add(layer, link)
        passwd = b"root:x:0:0:root:/:/bin/sh\nnobody:x:65534:65534:nobody:/:/bin/sh\n"
        info = tarfile.TarInfo("etc/passwd")
        info.size, info.mode = len(passwd), 0o644
        _add(layer, info, passwd)
    return out.getvalue()


def _blob(archive: tarfile.TarFile, data: bytes) -> str:
    digest = hashlib.sha256(data).hexdigest()
    info = tarfile.TarInfo(f"blobs/sha256/{digest}")
    info.size, info.mode = len(data), 0o644
    _add(archive, info, data)
    return f"sha256:{digest}"


def build_archive(busybox: bytes, names: tuple[str, ...]) -> bytes:
    """An OCI image-layout tar of the busybox image, with one index entry per image name (pure)."""
    layer = _layer(busybox)
    compressed = gzip.compress(layer, mtime=0)
    config = {
        "architecture": "amd64",
        "os": "linux",
        "config": {"Entrypoint": _PAUSE, "Env": ["PATH=/bin"], "WorkingDir": "/"},
        "rootfs": {"type": "layers", "diff_ids": [f"sha256:{hashlib.sha256(layer).hexdigest()}"]},
    }
    out = io.BytesIO()
    with tarfile.open(fileobj=out, mode="w", format=tarfile.PAX_FORMAT) as archive:
        config_bytes = json.dumps(config, sort_keys=True).encode()
        manifest = {
            "schemaVersion": 2,
            "mediaType": "application/vnd.oci.image.manifest.v1+json",
            "config": {
                "mediaType": "application/vnd.oci.image.config.v1+json",
                "digest": _blob(archive, config_bytes),
                "size": len(config_bytes),
            },
            "layers": [
                {
                    "mediaType": "application/vnd.oci.image.layer.v1.tar+gzip",
                    "digest": _blob(archive, compressed),
                    "size": len(compressed),
                }
            ],
        }
        manifest_bytes = json.dumps(manifest, sort_keys=True).encode()
        manifest_digest = _blob(archive, manifest_bytes)
        index = {
            "schemaVersion": 2,
            "manifests": [
                {
                    "mediaType": "application/vnd.oci.image.manifest.v1+json",
                    "digest": manifest_digest,
                    "size": len(manifest_bytes),
                    "annotations": {
                        "io.containerd.image.name": name,
                        "org.opencontainers.image.ref.name": name,
                    },
                }
                for name in names
            ],
        }
        for name, data in (
            ("oci-layout", json.dumps({"imageLayoutVersion": "1.0.0"}).encode()),
            ("index.json", json.dumps(index, sort_keys=True).encode()),
        ):
            info = tarfile.TarInfo(name)
            info.size, info.mode = len(data), 0o644
            _add(archive, info, data)
    return out.getvalue()


def local_archive(cache_dir: Path) -> Path:
    """The archive of `TEST_IMAGE`, written once per content (named by its digest)."""
    if not BUSYBOX.is_file():
        raise ImageError(f"{BUSYBOX} is missing: install busybox-static (hack/setup-node-runtime.sh)")
    archive = build_archive(BUSYBOX.read_bytes(), (TEST_IMAGE,))
    path = cache_dir / f"busybox-{hashlib.sha256(archive).hexdigest()[:16]}.oci.tar"
    if not path.exists():
        cache_dir.mkdir(parents=True, exist_ok=True)
        path.with_suffix(".tmp").write_bytes(archive)
        path.with_suffix(".tmp").replace(path)
    return path

