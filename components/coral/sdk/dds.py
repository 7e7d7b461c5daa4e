"""The DDS settings a Coral process starts with, applied before it initialises ROS.

Components of one robot start together and discover each other in any order. When a reliable
reader learns of a writer only after the writer's first samples went out (3 of 15 SLAM missions
measured on a 2-core machine), it gets them once the writer next announces what it holds:
FastDDS's writers do that every 3 s, so a snapshot or a first scan arrived up to 3 s late
(docs/architecture.md, the SLAM mission's figures). The packaged profile (`fastdds.xml`) makes
that 0.1 s. A writer announces only while a reader has not acknowledged everything, so the
shorter period costs no traffic in steady state; while a mission publishes, its timer wakes each
process's DDS event thread about twice as often as the 3 s default does (docs/architecture.md,
"Where the SLAM mission's CPU goes").

Writers also publish synchronously: rmw_fastrtps hands every sample to a FastDDS thread of its own
by default, so each message a component sends (a scan, a service call or its answer, a heartbeat)
wakes a second thread to send it. On a robot computer whose cores a registration keeps busy, each
of those wake-ups preempts it; sent from the publishing thread, a message wakes no second thread
(docs/architecture.md, "Where the SLAM mission's CPU goes").

A component that publishes bursts of large messages (`LARGE_MESSAGES`: the bag player) gets a
second profile, `fastdds_large_data.xml`: the same, with a shared-memory segment of 16 MB instead
of FastDDS's 512 kB. The default segment holds two 260 kB lidar scans; a burst finds it full while
the readers' threads wait for a CPU, and every scan that does not fit waits for the next heartbeat
to be sent again. On the SLAM mission that stretched the bag's arrival over up to 0.8 s of
registration instead of 0.2 to 0.3 s (docs/architecture.md, "Where the SLAM mission's CPU goes").
FastDDS fills the whole segment in `/dev/shm` when the process starts (a pod's is 64 MB), so a
component asks for it.

A user's own profile always wins: nothing is set when either profile variable is set, or when
FastDDS's own default file is in the working directory. The large-data profile replaces FastDDS's
builtin transports, so a user's choice of those (`FASTDDS_BUILTIN_TRANSPORTS`) keeps the default one.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping
from pathlib import Path

PROFILE = Path(__file__).with_name("fastdds.xml")
LARGE_DATA_PROFILE = Path(__file__).with_name("fastdds_large_data.xml")
PROFILE_VARIABLE = "FASTRTPS_DEFAULT_PROFILES_FILE"
# FastDDS 2 reads the first, FastDDS 3 the second; a user's setting of either is theirs.
USER_PROFILE_VARIABLES = (PROFILE_VARIABLE, "FASTDDS_DEFAULT_PROFILES_FILE")
# Loaded by FastDDS from the working directory when no variable names a file.
DEFAULT_PROFILE_FILES = ("DEFAULT_FASTRTPS_PROFILES.xml", "DEFAULT_FASTDDS_PROFILES.xml")
# FastDDS's builtin transports as the user chose them (`LARGE_DATA`, `UDPv4`, ...).
BUILTIN_TRANSPORTS_VARIABLE = "FASTDDS_BUILTIN_TRANSPORTS"
# rmw_fastrtps's choice between its own sending thread (ASYNCHRONOUS, its default) and the caller's.
PUBLICATION_MODE_VARIABLE = "RMW_FASTRTPS_PUBLICATION_MODE"


def use_coral_profile(
    environ: MutableMapping[str, str] | None = None, cwd: Path | None = None, *, large_messages: bool = False
) -> bool:
    """Points FastDDS at Coral's profile (the large-data one for a process that publishes large
    messages), and rmw_fastrtps at synchronous publication unless the user chose a mode; does
    nothing when the user chose a profile. True when it set the profile."""
    environ = os.environ if environ is None else environ
    if any(environ.get(name) for name in USER_PROFILE_VARIABLES):
        return False
    folder = Path.cwd() if cwd is None else cwd
    if any((folder / name).is_file() for name in DEFAULT_PROFILE_FILES):
        return False
    large = large_messages and not environ.get(BUILTIN_TRANSPORTS_VARIABLE)
    environ[PROFILE_VARIABLE] = str(LARGE_DATA_PROFILE if large else PROFILE)
    if not environ.get(PUBLICATION_MODE_VARIABLE):
        environ[PUBLICATION_MODE_VARIABLE] = "SYNCHRONOUS"
    return True
