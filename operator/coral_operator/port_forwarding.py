"""Forward local TCP ports to a pod's ports through the API server, as `kubectl port-forward` does:
the user's credentials, RBAC (`create` on `pods/portforward`) and the audit log apply. Used by
`coral groot2` and `coral tree watch SYSTEM ROBOT`.

It uses the Kubernetes Python client's port-forward (a websocket per connection to
`pods/NAME/portforward`) rather than shelling out to kubectl: the same kubeconfig and client the
rest of `coral` uses, and no second binary whose version must match the cluster's. Each local
connection gets a websocket of its own, so clients that reconnect (ZeroMQ does after any error)
and several clients at once work.
"""

from __future__ import annotations

import contextlib
import select
import socket
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException
from kubernetes.stream import portforward

CHUNK = 64 * 1024
POLL_S = 0.5
"""How often idle relays look whether the forward was closed."""


class ForwardError(Exception):
    """The API server refused the port-forward; the message says why."""


def open_stream(api_client: k8s.ApiClient, namespace: str, pod: str, port: int) -> Any:
    """One connection to `port` inside the pod, through the API server: the client's forward, whose
    `socket(port)` carries the bytes and `error(port)` what the kubelet said went wrong.

    Raises:
        ForwardError: the API server or the kubelet refused (RBAC, no such pod, not running).
    """
    core = k8s.CoreV1Api(api_client)
    try:
        forward = portforward(core.connect_get_namespaced_pod_portforward, pod, namespace, ports=str(port))
    except ApiException as error:
        # The websocket client folds the handshake's HTTP status into `reason`.
        raise ForwardError(
            f"cannot forward to pod {pod} in namespace {namespace}: {error.reason or error}; forwarding "
            "needs `create` on `pods/portforward` there"
        ) from error
    return forward


def _relay(left: socket.socket, right: socket.socket, stopped: threading.Event) -> None:
    """Copy bytes both ways until either side closes or the forward stops."""
    try:
        while not stopped.is_set():
            readable, _, _ = select.select([left, right], [], [], POLL_S)
            for source in readable:
                data = source.recv(CHUNK)
                if not data:
                    return
                (right if source is left else left).sendall(data)
    except OSError:
        return
    finally:
        for end in (left, right):
            with contextlib.suppress(OSError):
                end.close()


@dataclass
class PortForward:
    """Local listeners on `host`, one per (local port, pod port) pair, each connection relayed to
    the pod. A local port of 0 takes a free one (`local_ports` says which). Use as a context
    manager, or `start` and `close`."""

    api_client: k8s.ApiClient
    namespace: str
    pod: str
    pairs: list[tuple[int, int]]
    host: str = "127.0.0.1"
    on_error: Callable[[str], None] = lambda _message: None
    """Told, in a sentence, when a connection could not be forwarded (the listener goes on)."""
    local_ports: list[int] = field(default_factory=list)
    _listeners: list[socket.socket] = field(default_factory=list)
    _stopped: threading.Event = field(default_factory=threading.Event)

    def start(self) -> PortForward:
        """Bind every local port, then serve them on daemon threads.

        Raises:
            OSError: a local port is taken.
        """
        try:
            for local, remote in self.pairs:
                listener = socket.create_server((self.host, local), reuse_port=False)
                self._listeners.append(listener)
                self.local_ports.append(listener.getsockname()[1])
                threading.Thread(target=self._accept, args=(listener, remote), daemon=True).start()
        except OSError:
            self.close()
            raise
        return self

    def _accept(self, listener: socket.socket, remote: int) -> None:
        while not self._stopped.is_set():
            try:
                connection, _ = listener.accept()
            except OSError:
                return
            threading.Thread(target=self._serve, args=(connection, remote), daemon=True).start()

    def _serve(self, connection: socket.socket, remote: int) -> None:
        try:
            stream = open_stream(self.api_client, self.namespace, self.pod, remote)
        except ForwardError as error:
            self.on_error(str(error))
            connection.close()
            return
        _relay(connection, stream.socket(remote), self._stopped)
        if stream.error(remote):
            self.on_error(f"pod {self.pod} port {remote}: {stream.error(remote).strip()}")

    def close(self) -> None:
        self._stopped.set()
        for listener in self._listeners:
            with contextlib.suppress(OSError):
                listener.shutdown(socket.SHUT_RDWR)
            listener.close()

    def __enter__(self) -> PortForward:
        return self.start()

    def __exit__(self, *_exc: object) -> None:
        self.close()
