"""A stop signal ends a process whose main thread is busy waiting on the very Event the signal sets."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap

import pytest

# The main thread takes and releases the Event's lock as fast as it can: a handler that set the
# Event from the main thread would, most times, wait on that lock while its own thread held it.
BUSY_WAITER = textwrap.dedent(
    """
    import threading
    from coral.stop_signals import relay_stop_signals

    stopping = threading.Event()
    received = []

    def stopped(signum):
        received.append(signum)
        stopping.set()

    relay_stop_signals(stopped)
    print("ready", flush=True)
    while not stopping.is_set():
        stopping.wait(0)
    print("stopped by", received[0], flush=True)
    """
)


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_every_stop_signal_ends_a_main_thread_waiting_on_the_event_it_sets(signum: int) -> None:
    hung = 0
    for _ in range(10):
        process = subprocess.Popen([sys.executable, "-c", BUSY_WAITER], stdout=subprocess.PIPE, text=True)
        assert process.stdout is not None
        assert process.stdout.readline().strip() == "ready"
        process.send_signal(signum)
        try:
            out, _ = process.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            hung += 1
            process.kill()
            process.communicate()
            continue
        assert process.returncode == 0 and out.strip() == f"stopped by {int(signum)}"
    assert hung == 0, f"{hung} of 10 processes never stopped"
