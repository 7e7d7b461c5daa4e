"""A robot's uplink: host services (the API server, the registry) at their host addresses inside the robot.

Run as a process per robot by `realrobots` (`python -m coral_testbed.cluster.uplink NETNS PORT...`).
Each listening socket is made inside the robot's network namespace (the thread enters it with
setns(2) and leaves again); each accepted connection is piped to the same port on the host's
127.0.0.1. So inside the robot, 127.0.0.1:<apiserver port> is the API server (its certificate
matches) and 127.0.0.1:5000 the registry. Cutting a robot's link stops this process, so a cut
robot loses the control plane and the registry too.
"""

from __future__ import annotations

import argparse
import ctypes
import os
import signal
import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager

_CLONE_NEWNET = 0x40000000


def _setns(fd: int) -> None:
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.setns(fd, _CLONE_NEWNET) != 0:
        error = ctypes.get_errno()
        raise OSError(error, f"setns failed: {os.strerror(error)}")


@contextmanager
def entered_netns(path: str) -> Iterator[None]:
    """Runs the block with this thread inside the network namespace at `path`."""
    own = os.open("/proc/thread-self/ns/net", os.O_RDONLY)
    target = os.open(path, os.O_RDONLY)
    try:
        _setns(target)
        try:
            yield
        finally:
            _setns(own)
    finally:
        os.close(target)
        os.close(own)


def listen_inside(netns_path: str, port: int) -> socket.socket:
    with entered_netns(netns_path):
        server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        server.bind(("127.0.0.1", port))
        server.listen(64)
    return server


def _pipe(source: socket.socket, sink: socket.socket) -> None:
    try:
        while data := source.recv(65536):
            sink.sendall(data)
    except OSError:
        pass
    finally:
        for end in (source, sink):
            try:
                end.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass


def _serve(server: socket.socket, port: int) -> None:
    while True:
        try:
            client, _ = server.accept()
        except OSError:
            return  # the listening socket was closed: the offer is withdrawn
        try:
            upstream = socket.create_connection(("127.0.0.1", port), timeout=10)
            upstream.settimeout(None)
        except OSError:
            client.close()
            continue
        for source, sink in ((client, upstream), (upstream, client)):
            threading.Thread(target=_pipe, args=(source, sink), daemon=True).start()


@contextmanager
def offered_inside(netns_path: str, port: int, host_port: int) -> Iterator[None]:
    """Offers the host's 127.0.0.1:`host_port` at 127.0.0.1:`port` inside the robot, from a thread of
    this process, for the duration of the block: a service a test brings to one robot (a registry
    at a new address) without touching its uplink."""
    server = listen_inside(netns_path, port)
    threading.Thread(target=_serve, args=(server, host_port), daemon=True).start()
    try:
        yield
    finally:
        try:
            server.shutdown(socket.SHUT_RDWR)  # wakes the thread blocked in accept()
        except OSError:
            pass
        server.close()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("netns", help="path of the robot's network namespace, e.g. /run/netns/NAME")
    parser.add_argument("ports", nargs="+", type=int, help="host ports to offer inside the robot")
    args = parser.parse_args(argv)
    servers = [(listen_inside(args.netns, port), port) for port in args.ports]
    for server, port in servers:
        threading.Thread(target=_serve, args=(server, port), daemon=True).start()
    print(f"uplink into {args.netns}: ports {args.ports}", flush=True)
    signal.sigwait({signal.SIGTERM, signal.SIGINT})


if __name__ == "__main__":
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM, signal.SIGINT})
    main()
