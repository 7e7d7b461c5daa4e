"""The local image registry: Debian's docker-registry over plain HTTP, storage in the cache folder.

Kubelets' containerd pulls from it by name, as from any registry: robots map `coral.local` and
the registry's own address to it (docs/kind.md), so `coral.local/coral/executor:0.1.0` and
`127.0.0.1:5000/coral/executor:0.1.0` name the same image. Several registry processes may
serve the same storage on different addresses. `start`/`stop` are for fixtures, which own their
process; `up`/`down` keep one registry per address running across commands (`coral images
registry up`). Also a small client for what the build needs: a tag's manifest and config.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import socket
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from coral_testbed.cluster import processes
from coral_testbed.waiting import wait_for

DEFAULT_ADDRESS = "127.0.0.1:5000"
ADDRESS_ENV = "CORAL_REGISTRY"
"""Where the image fixtures and `coral images` find the registry (default `DEFAULT_ADDRESS`)."""
_MANIFEST_TYPES = ", ".join(
    (
        "application/vnd.oci.image.manifest.v1+json",
        "application/vnd.docker.distribution.manifest.v2+json",
    )
)


class RegistryError(RuntimeError):
    """The registry could not be started, reached or asked; the message says which address and why."""


@dataclass(frozen=True)
class Manifest:
    digest: str
    config_digest: str
    layers: tuple[tuple[str, int], ...]
    """(digest, compressed size) of each layer, base first."""


def configured_address() -> str:
    """`$CORAL_REGISTRY`, else 127.0.0.1:5000."""
    return os.environ.get(ADDRESS_ENV) or DEFAULT_ADDRESS


def split_address(address: str) -> tuple[str, int]:
    """("127.0.0.1", 5000) from "127.0.0.1:5000"; raises ValueError naming a bad address."""
    host, sep, port = address.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"registry address {address!r} is not HOST:PORT")
    return host, int(port)


def render_config(address: str, storage: Path) -> str:
    """The docker-registry configuration (YAML is a superset of JSON) for one address."""
    config = {
        "version": 0.1,
        "log": {"level": "warn", "fields": {"service": "registry"}},
        "storage": {
            "filesystem": {"rootdirectory": str(storage)},
            "delete": {"enabled": True},
            "cache": {"blobdescriptor": "inmemory"},
        },
        "http": {"addr": address, "headers": {"X-Content-Type-Options": ["nosniff"]}},
    }
    return json.dumps(config, indent=2)


def _get(address: str, path: str, accept: str = "application/json") -> tuple[dict[str, Any], str] | None:
    """(JSON body, Docker-Content-Digest) of GET http://address/path, None on 404."""
    request = urllib.request.Request(f"http://{address}{path}", headers={"Accept": accept})
    try:
        with urllib.request.urlopen(request, timeout=10) as response:
            body = json.loads(response.read())
            return body, response.headers.get("Docker-Content-Digest", "")
    except urllib.error.HTTPError as error:
        if error.code == 404:
            return None
        raise RegistryError(f"registry at {address}: GET {path} answered {error.code}") from error
    except (urllib.error.URLError, OSError) as error:
        raise RegistryError(f"registry at {address} cannot be reached: {error}") from error


def is_serving(address: str) -> bool:
    try:
        return _get(address, "/v2/") is not None
    except RegistryError:
        return False


def manifest(address: str, repository: str, tag: str) -> Manifest | None:
    """The manifest `repository:tag` points at, None if the registry has no such tag."""
    found = _get(address, f"/v2/{repository}/manifests/{tag}", accept=_MANIFEST_TYPES)
    if found is None:
        return None
    body, digest = found
    layers = tuple((layer["digest"], int(layer["size"])) for layer in body.get("layers", []))
    return Manifest(digest=digest, config_digest=body["config"]["digest"], layers=layers)


def image_config(address: str, repository: str, config_digest: str) -> dict[str, Any]:
    """The image config blob (its `config` holds Entrypoint, User, Labels, ...)."""
    found = _get(address, f"/v2/{repository}/blobs/{config_digest}")
    if found is None:
        raise RegistryError(f"registry at {address} lacks config {config_digest} of {repository}")
    return found[0]


def manifest_document(address: str, repository: str, tag: str) -> dict[str, Any] | None:
    """The manifest `repository:tag` points at, as the registry serves it; None if it has no such tag."""
    found = _get(address, f"/v2/{repository}/manifests/{tag}", accept=_MANIFEST_TYPES)
    return None if found is None else found[0]


def _send(request: urllib.request.Request) -> str:
    """Sends a write to the registry; its Docker-Content-Digest."""
    try:
        with urllib.request.urlopen(request, timeout=60) as answer:
            return str(answer.headers.get("Docker-Content-Digest", ""))
    except (urllib.error.URLError, OSError) as error:
        raise RegistryError(f"registry: {request.method} {request.full_url} failed: {error}") from error


def put_blob(address: str, repository: str, body: bytes) -> str:
    """Uploads `body` as a blob of `repository` (one monolithic upload); its digest."""
    digest = "sha256:" + hashlib.sha256(body).hexdigest()
    start = urllib.request.Request(f"http://{address}/v2/{repository}/blobs/uploads/", method="POST")
    try:
        with urllib.request.urlopen(start, timeout=10) as answer:
            location = answer.headers["Location"]
    except (urllib.error.URLError, OSError) as error:
        raise RegistryError(f"registry at {address}: an upload to {repository} failed: {error}") from error
    if location.startswith("/"):
        location = f"http://{address}{location}"
    joiner = "&" if "?" in location else "?"
    _send(
        urllib.request.Request(
            f"{location}{joiner}digest={digest}",
            data=body,
            method="PUT",
            headers={"Content-Type": "application/octet-stream"},
        )
    )
    return digest


def put_manifest(address: str, repository: str, tag: str, document: dict[str, Any], media_type: str) -> str:
    """Tags `document` (its blobs uploaded before) as `repository:tag`; the manifest's digest."""
    return _send(
        urllib.request.Request(
            f"http://{address}/v2/{repository}/manifests/{tag}",
            data=json.dumps(document).encode(),
            method="PUT",
            headers={"Content-Type": media_type},
        )
    )


def repositories(address: str) -> list[str]:
    found = _get(address, "/v2/_catalog?n=1000")
    return [] if found is None else list(found[0].get("repositories", []))


def _port_is_free(address: str) -> bool:
    host, port = split_address(address)
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError:
            return False
    return True


def free_address(host: str = "127.0.0.1") -> str:
    """HOST:PORT with a port the kernel just reported free (for a fixture's own registry)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind((host, 0))
        return f"{host}:{probe.getsockname()[1]}"


def start(address: str, storage: Path, state_dir: Path, die_with_parent: bool = False) -> processes.Recorded:
    """Starts docker-registry on `address` over `storage` and waits until it answers.

    Raises:
        RegistryError: the binary is missing, the address is taken, or it did not come up.
    """
    split_address(address)
    binary = shutil.which("docker-registry")
    if binary is None:
        raise RegistryError("docker-registry is not installed; run `sudo bash hack/setup-node-runtime.sh`")
    if not _port_is_free(address):
        raise RegistryError(f"cannot start a registry on {address}: the address is in use")
    storage.mkdir(parents=True, exist_ok=True)
    state_dir.mkdir(parents=True, exist_ok=True)
    name = f"registry-{address.replace(':', '-')}"
    config = state_dir / f"{name}.yaml"
    config.write_text(render_config(address, storage))
    process = processes.spawn(
        name, [binary, "serve", str(config)], state_dir / f"{name}.log", die_with_parent=die_with_parent
    )
    try:
        wait_for(
            lambda: is_serving(address) or not processes.is_alive(process),
            timeout=30,
            message=f"registry on {address}",
        )
    except Exception:
        processes.stop(process)
        raise
    if not processes.is_alive(process):
        raise RegistryError(f"registry on {address} exited:\n{processes.log_tail(process.log)}")
    return process


def stop(process: processes.Recorded) -> None:
    processes.stop(process)


def _record_path(state_dir: Path, address: str) -> Path:
    return state_dir / f"registry-{address.replace(':', '-')}.json"


def running(state_dir: Path, address: str) -> processes.Recorded | None:
    """The registry `up` started on `address`, if it is still alive."""
    record = _record_path(state_dir, address)
    try:
        process = processes.Recorded.from_json(json.loads(record.read_text()))
    except (OSError, ValueError, KeyError):
        return None
    return process if processes.is_alive(process) else None


def up(address: str, storage: Path, state_dir: Path) -> tuple[processes.Recorded, bool]:
    """Keeps a registry on `address` running beyond this process; (process, whether it was started)."""
    process = running(state_dir, address)
    if process is not None:
        return process, False
    process = start(address, storage, state_dir)
    _record_path(state_dir, address).write_text(json.dumps(process.to_json()))
    return process, True


def down(state_dir: Path, address: str) -> bool:
    """Stops the registry `up` started on `address`; False if none was running."""
    process = running(state_dir, address)
    _record_path(state_dir, address).unlink(missing_ok=True)
    if process is None:
        return False
    processes.stop(process)
    return True


def recorded_addresses(state_dir: Path) -> list[str]:
    """Addresses of the registries `up` started that are still alive."""
    found = []
    for record in sorted(state_dir.glob("registry-*.json")):
        try:
            process = processes.Recorded.from_json(json.loads(record.read_text()))
        except (OSError, ValueError, KeyError):
            continue
        if processes.is_alive(process):
            host_port = record.stem.removeprefix("registry-")
            host, _, port = host_port.rpartition("-")
            found.append(f"{host}:{port}")
    return found
