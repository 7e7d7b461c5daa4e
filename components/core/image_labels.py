"""An image's labels read from its registry by digest (registry HTTP API v2), for preflight.

A reference's tag is resolved to a digest with one manifest request; the config blob, whose
`config.Labels` hold the declaration, is read once per digest and then kept: a digest names
immutable content, so a fleet of a hundred robots on five images costs five reads, ever. Every
request has a short timeout, so an unreachable registry costs a pass seconds, not minutes.
Credentials are the `auths` of a Docker config (a pull secret's `.dockerconfigjson`); a registry
that asks for a bearer token gets one from the realm it names. Loopback and `.local` registries
are spoken to over plain HTTP, as the project's local registry serves; others over HTTPS.
"""

from __future__ import annotations

import base64
import json
import re
import threading
import urllib.error
import urllib.parse
import urllib.request
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

TIMEOUT_SECONDS = 3.0
LABELS_KEPT = 1024
DEFAULT_REGISTRY = "registry-1.docker.io"
_MANIFEST_TYPES = ", ".join(
    (
        "application/vnd.oci.image.manifest.v1+json",
        "application/vnd.docker.distribution.manifest.v2+json",
        "application/vnd.oci.image.index.v1+json",
        "application/vnd.docker.distribution.manifest.list.v2+json",
    )
)
_BEARER = re.compile(r'(\w+)="([^"]*)"')


class LabelsError(RuntimeError):
    """The image's labels could not be read; the message names the image and why."""


@dataclass(frozen=True)
class Reference:
    registry: str
    repository: str
    tag: str | None
    digest: str | None

    @property
    def scheme(self) -> str:
        host = self.registry.split(":")[0]
        plain = host in ("localhost", "127.0.0.1", "::1") or host.endswith(".local")
        return "http" if plain else "https"


def parse_reference(image: str) -> Reference:
    """`[registry/]repository[:tag][@digest]` as container runtimes read it."""
    rest, _, digest = image.partition("@")
    first, slash, remainder = rest.partition("/")
    if slash and ("." in first or ":" in first or first == "localhost"):
        registry, path = first, remainder
    else:
        registry, path = DEFAULT_REGISTRY, rest
        if "/" not in path:
            path = f"library/{path}"
    name, colon, tag = path.rpartition(":")
    if not colon or "/" in tag:
        name, tag = path, ""
    return Reference(registry, name, tag or (None if digest else "latest"), digest or None)


def _basic(auths: Mapping[str, Any], registry: str) -> str | None:
    for key in (registry, f"https://{registry}", f"http://{registry}", f"https://{registry}/v1/"):
        entry = auths.get(key)
        if isinstance(entry, dict):
            if entry.get("auth"):
                return str(entry["auth"])
            if entry.get("username"):
                return base64.b64encode(f"{entry['username']}:{entry.get('password', '')}".encode()).decode()
    return None


class ImageLabels:
    """Labels by image digest, read through the registry API; thread safe, one per process."""

    def __init__(self, timeout: float = TIMEOUT_SECONDS, size: int = LABELS_KEPT) -> None:
        self.timeout = timeout
        self._size = size
        self._lock = threading.Lock()
        self._kept: OrderedDict[str, dict[str, str]] = OrderedDict()
        self.reads = 0
        """Config blobs read from registries (not from what is kept): how often the cache missed."""

    def digest_of(self, image: str, auths: Mapping[str, Any] | None = None) -> str:
        """The manifest digest `image` names now (its own digest when it carries one)."""
        reference = parse_reference(image)
        if reference.digest:
            return reference.digest
        _, headers = self._get(
            reference, f"manifests/{reference.tag}", _MANIFEST_TYPES, auths or {}, head=True
        )
        digest = headers.get("Docker-Content-Digest")
        if not digest:
            raise LabelsError(f"image {image}: the registry gave no digest for tag {reference.tag}")
        return digest

    def labels(self, image: str, auths: Mapping[str, Any] | None = None) -> tuple[str, dict[str, str]]:
        """(digest, labels) of `image`; raises `LabelsError` when the registry cannot tell."""
        auths = auths or {}
        digest = self.digest_of(image, auths)
        with self._lock:
            if digest in self._kept:
                self._kept.move_to_end(digest)
                return digest, dict(self._kept[digest])
        reference = parse_reference(image)
        labels = self._read_labels(image, reference, digest, auths)
        with self._lock:
            self.reads += 1
            self._kept[digest] = labels
            while len(self._kept) > self._size:
                self._kept.popitem(last=False)
        return digest, dict(labels)

    def _read_labels(
        self, image: str, reference: Reference, digest: str, auths: Mapping[str, Any]
    ) -> dict[str, str]:
        body, _ = self._get(reference, f"manifests/{digest}", _MANIFEST_TYPES, auths)
        manifest = json.loads(body)
        if "manifests" in manifest:
            # An index: the labels are those of its linux/amd64 image, else of its first.
            entries = manifest["manifests"] or []
            chosen = next(
                (m for m in entries if (m.get("platform") or {}).get("architecture") == "amd64"),
                entries[0] if entries else None,
            )
            if chosen is None:
                raise LabelsError(f"image {image}: its index lists no image")
            body, _ = self._get(reference, f"manifests/{chosen['digest']}", _MANIFEST_TYPES, auths)
            manifest = json.loads(body)
        config_digest = (manifest.get("config") or {}).get("digest")
        if not config_digest:
            raise LabelsError(f"image {image}: its manifest names no config")
        body, _ = self._get(reference, f"blobs/{config_digest}", "application/json", auths)
        config = json.loads(body)
        labels = (config.get("config") or {}).get("Labels") or {}
        return {str(k): str(v) for k, v in labels.items()}

    def _get(
        self, reference: Reference, path: str, accept: str, auths: Mapping[str, Any], head: bool = False
    ) -> tuple[bytes, Mapping[str, str]]:
        url = f"{reference.scheme}://{reference.registry}/v2/{reference.repository}/{path}"
        basic = _basic(auths, reference.registry)
        authorization = f"Basic {basic}" if basic else None
        for attempt in range(2):
            request = urllib.request.Request(
                url, method="HEAD" if head else "GET", headers={"Accept": accept}
            )
            if authorization:
                request.add_header("Authorization", authorization)
            try:
                with urllib.request.urlopen(request, timeout=self.timeout) as response:
                    return response.read(), response.headers
            except urllib.error.HTTPError as error:
                challenge = error.headers.get("WWW-Authenticate", "") if error.headers else ""
                if error.code == 401 and attempt == 0 and challenge.lower().startswith("bearer"):
                    authorization = f"Bearer {self._token(challenge, basic)}"
                    continue
                raise LabelsError(
                    f"image {reference.registry}/{reference.repository}: GET {path} answered {error.code}"
                ) from error
            except (urllib.error.URLError, OSError, ValueError) as error:
                raise LabelsError(f"registry {reference.registry} cannot be reached: {error}") from error
        raise LabelsError(f"registry {reference.registry} refused the credentials")

    def _token(self, challenge: str, basic: str | None) -> str:
        fields = dict(_BEARER.findall(challenge))
        query = urllib.parse.urlencode({k: v for k, v in fields.items() if k in ("service", "scope")})
        request = urllib.request.Request(f"{fields.get('realm', '')}?{query}")
        if basic:
            request.add_header("Authorization", f"Basic {basic}")
        try:
            with urllib.request.urlopen(request, timeout=self.timeout) as response:
                answer = json.loads(response.read())
        except (urllib.error.URLError, OSError, ValueError) as error:
            raise LabelsError(f"no registry token from {fields.get('realm')}: {error}") from error
        return str(answer.get("token") or answer.get("access_token") or "")
