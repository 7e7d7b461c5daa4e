"""A verb that runs until Ctrl-C stops on SIGINT also when it was started with SIGINT ignored, as a
shell starts its background jobs (`coral groot2 ... &`, a supervisor, a script)."""

from __future__ import annotations

import signal
import subprocess
import sys

WAITS_FOR_CTRL_C = """
import sys, threading
from coral_core.command import stop_on_ctrl_c
stop_on_ctrl_c()
# Inside the try: the Ctrl-C may arrive as soon as the line is out.
try:
    print("waiting", flush=True)
    threading.Event().wait()
except KeyboardInterrupt:
    print("stopped", flush=True)
    sys.exit(130)
"""


def test_a_verb_started_with_sigint_ignored_still_stops_on_ctrl_c() -> None:
    process = subprocess.Popen(
        [sys.executable, "-c", WAITS_FOR_CTRL_C],
        stdout=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),
    )
    assert process.stdout is not None and process.stdout.readline() == "waiting\n"
    process.send_signal(signal.SIGINT)
    out, _ = process.communicate(timeout=10)
    assert (process.returncode, out) == (130, "stopped\n")

