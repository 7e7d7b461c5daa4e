"""A TCP forwarder that gives processes inside a robot's network namespace the Kubernetes API.

The listening socket is created inside the robot's namespace (the creating thread enters it with
setns(2) and leaves again), while connections to the API server are made from the runner's own
namespace. Processes on the robot therefore reach the API at the very address in the cluster's
kubeconfig (127.0.0.1:<port>), and the server certificate still matches. Used by `runner.robots`;
`set_enabled(False)` drops every connection and refuses new ones, which is how a cut link looks
to a robot's API clients.
"""

from __future__ import annotations

import ctypes
import os
import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager

_CLONE_NEWNET = 0x40000000
_libc = ctypes.CDLL(None, use_errno=True)


def _setns(fd: int) -> None:
    if _libc.setns(fd, _CLONE_NEWNET) != 0:
        error = ctypes.get_errno()
        raise OSError(error, f"setns failed: {os.strerror(error)}")


@contextmanager
def entered_netns(netns: str | None) -> Iterator[None]:
    """Runs the block with this thread inside `netns` (a name under /run/netns); None stays put."""
    if netns is None:
        yield
        return
    own = os.open("/proc/thread-self/ns/net", os.O_RDONLY)
    target = os.open(f"/run/netns/{netns}", os.O_RDONLY)
    try:
        _setns(target)
        try:
            yield
        finally:
            _setns(own)
    finally:
        os.close(target)
        os.close(own)


class Forwarder:
    """Listens on `listen` (inside `netns`) and pipes each connection to `target`."""

    def __init__(self, netns: str | None, listen: tuple[str, int], target: tuple[str, int]) -> None:
        self.target = target
        self._enabled = True
        self._lock = threading.Lock()
        self._open: set[socket.socket] = set()
        with entered_netns(netns):
            self._server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            self._server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self._server.bind(listen)
            self._server.listen(64)
        self.address: tuple[str, int] = self._server.getsockname()
        self._closed = False
        self._thread = threading.Thread(target=self._accept_loop, name=f"forwarder-{netns}", daemon=True)
        self._thread.start()

    def set_enabled(self, enabled: bool) -> None:
        with self._lock:
            self._enabled = enabled
            doomed = list(self._open) if not enabled else []
        for sock in doomed:
            _close(sock)

    def close(self) -> None:
        self._closed = True
        _close(self._server)
        self.set_enabled(False)
        self._thread.join(timeout=5)

    def _accept_loop(self) -> None:
        while not self._closed:
            try:
                client, _ = self._server.accept()
            except OSError:
                return
            if not self._enabled:
                _close(client)
                continue
            try:
                upstream = socket.create_connection(self.target, timeout=10)
                upstream.settimeout(None)
            except OSError:
                _close(client)
                continue
            with self._lock:
                self._open.update((client, upstream))
            for source, sink in ((client, upstream), (upstream, client)):
                threading.Thread(target=self._pump, args=(source, sink), daemon=True).start()

    def _pump(self, source: socket.socket, sink: socket.socket) -> None:
        try:
            while True:
                data = source.recv(65536)
                if not data:
                    break
                sink.sendall(data)
        except OSError:
            pass
        finally:
            with self._lock:
                self._open.discard(source)
                self._open.discard(sink)
            _close(source)
            _close(sink)


def _close(sock: socket.socket) -> None:
    try:
        sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass
    sock.close()
