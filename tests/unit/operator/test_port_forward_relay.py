"""The relay of `coral groot2`'s forwards (`coral_operator.port_forwarding`): bytes go both ways
unchanged, and one side closing closes the other, so a client that hangs up frees its stream
through the API server. Real sockets; the API server's side is a socket pair here, as the
Kubernetes client's own forward hands one out."""

from __future__ import annotations

import socket
import threading

from coral_operator import port_forwarding


def _relayed() -> tuple[socket.socket, socket.socket, threading.Thread, threading.Event]:
    client, client_end = socket.socketpair()
    upstream_end, upstream = socket.socketpair()
    stopped = threading.Event()
    thread = threading.Thread(target=port_forwarding._relay, args=(client_end, upstream_end, stopped))
    thread.start()
    return client, upstream, thread, stopped


def _read(sock: socket.socket, size: int) -> bytes:
    sock.settimeout(10)
    data = b""
    while len(data) < size:
        chunk = sock.recv(size - len(data))
        if not chunk:
            break
        data += chunk
    return data


def test_bytes_cross_both_ways_unchanged() -> None:
    client, upstream, thread, stopped = _relayed()
    request = bytes(range(256)) * 1000  # larger than one read
    client.sendall(request)
    assert _read(upstream, len(request)) == request
    upstream.sendall(b"reply")
    assert _read(client, 5) == b"reply"
    stopped.set()
    thread.join(timeout=10)
    assert not thread.is_alive()


def test_a_client_hanging_up_closes_the_stream_through_the_api_server() -> None:
    client, upstream, thread, _stopped = _relayed()
    client.close()
    thread.join(timeout=10)
    assert not thread.is_alive()
    upstream.settimeout(10)
    assert upstream.recv(1) == b""


def test_the_pod_side_closing_closes_the_client() -> None:
    client, upstream, thread, _stopped = _relayed()
    upstream.close()
    thread.join(timeout=10)
    client.settimeout(10)
    assert client.recv(1) == b""
