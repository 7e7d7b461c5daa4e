"""A ROS domain no other process on this machine uses: for the demo's robots, each test, a benchmark.

Robots' pods reach the host through the cluster's network bridge, so a ROS process on the host on
the same domain (a `coral run` on the default domain 0, say) would hear and talk to them. Domains
are claimed with an exclusive file lock in one folder, so the demo, the tests (the `ros_env` fixture),
the benchmarks and parallel runs on the same machine never share one. The lock lasts while the
returned fd is open.
"""

from __future__ import annotations

import fcntl
import os
import tempfile
from pathlib import Path

# Domain IDs 1..101 are valid on every platform and leave 0 (the ROS default) to people.
DOMAIN_RANGE = range(1, 102)
LOCK_DIR = Path(tempfile.gettempdir()) / "coral-ros-domains"


def claim_domain(*, highest_first: bool = False) -> tuple[int, int]:
    """(domain id, lock fd) of a domain no other process on this machine holds; `highest_first`
    keeps a long-lived claimer (a benchmark) out of the low domains the tests take first."""
    LOCK_DIR.mkdir(parents=True, exist_ok=True)
    for domain in reversed(DOMAIN_RANGE) if highest_first else DOMAIN_RANGE:
        fd = os.open(LOCK_DIR / f"{domain}.lock", os.O_CREAT | os.O_RDWR, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            continue
        return domain, fd
    raise RuntimeError(f"every ROS domain in {DOMAIN_RANGE} is held by another process")
