"""A ROS domain no other process on this machine uses, for the demo's robots.

Robots of the runner reach the host through their bridge, so a ROS process on the host on the same
domain (a `coral run` on the default domain 0, say) would hear and talk to them. The demo claims a
domain with the lock files the test suite's `ros_env` fixture uses (same folder and range), so the
demo, the tests and other demos never share one. The lock lasts while the returned fd is open.
"""

from __future__ import annotations

import fcntl
import os
import tempfile
from pathlib import Path

DOMAIN_RANGE = range(1, 102)
LOCK_DIR = Path(tempfile.gettempdir()) / "coral-ros-domains"


def claim_domain() -> tuple[int, int]:
    """(domain id, lock fd) of a domain no other process on this machine holds."""
    LOCK_DIR.mkdir(parents=True, exist_ok=True)
    for domain in DOMAIN_RANGE:
        fd = os.open(LOCK_DIR / f"{domain}.lock", os.O_CREAT | os.O_RDWR, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            continue
        return domain, fd
    raise RuntimeError(f"every ROS domain in {DOMAIN_RANGE} is held by another process")
