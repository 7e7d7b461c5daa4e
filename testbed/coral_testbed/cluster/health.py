"""Health probes of the control-plane components over HTTP(S), used while starting and by `status`.

Each probe returns True when healthy and False on any connection or HTTP error, so callers can
poll it with `waiting.wait_for`.
"""

from __future__ import annotations

import http.client
import json
import ssl
import urllib.error
import urllib.request
from pathlib import Path


def _get(url: str, context: ssl.SSLContext | None, timeout: float) -> bytes | None:
    """The body of a 200 response, None on any error."""
    try:
        with urllib.request.urlopen(url, timeout=timeout, context=context) as response:
            return response.read() if response.status == 200 else None
    except (OSError, urllib.error.URLError, http.client.HTTPException, ValueError):
        return None


def _get_ok(url: str, context: ssl.SSLContext | None, timeout: float) -> bool:
    body = _get(url, context, timeout)
    return body is not None and body.strip() == b"ok"


def _insecure() -> ssl.SSLContext:
    # Controller manager and scheduler serve /healthz with self-signed certificates made at start.
    context = ssl.create_default_context()
    context.check_hostname = False
    context.verify_mode = ssl.CERT_NONE
    return context


def etcd_healthy(port: int, timeout: float = 3.0) -> bool:
    body = _get(f"http://127.0.0.1:{port}/health", None, timeout)
    try:
        return body is not None and json.loads(body).get("health") == "true"
    except ValueError:
        return False


def apiserver_ready(
    port: int, ca_cert: Path, client_cert: Path, client_key: Path, timeout: float = 5.0
) -> bool:
    context = ssl.create_default_context(cafile=str(ca_cert))
    context.load_cert_chain(str(client_cert), str(client_key))
    return _get_ok(f"https://127.0.0.1:{port}/readyz", context, timeout)


def component_healthy(port: int, timeout: float = 3.0) -> bool:
    """/healthz of kube-controller-manager or kube-scheduler (always readable without credentials)."""
    return _get_ok(f"https://127.0.0.1:{port}/healthz", _insecure(), timeout)


def kwok_healthy(port: int, timeout: float = 3.0) -> bool:
    return _get_ok(f"http://127.0.0.1:{port}/healthz", None, timeout)
