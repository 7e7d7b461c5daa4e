"""The Docker engine kind runs on: a dockerd of the project's own, or a user's Docker when asked.

The project's dockerd (Debian's `docker.io`, installed by `hack/setup-docker.sh`) listens on its own
socket with its own pid file and exec root, so it never clashes with a Docker the user runs, and
keeps its data root in the cache so the node image survives between runs. It is started so that
it leaves the host alone (docs/kind.md):

- `--iptables=false --ip-masq=false --ip-forward=false --bridge=none`: dockerd would otherwise turn
  on the host's `ip_forward` and write NAT rules; kind's nodes only need the network kind creates.
- `--default-runtime` is `hack/runc-within-bounding-set`: dockerd asks for every capability for
  `--privileged` (kind's nodes), and runc fails on one outside this machine's bounding set
  (CAP_SYS_RESOURCE here); the wrapper drops those before running runc.

`$CORAL_DOCKER_HOST` (say `unix:///var/run/docker.sock`) chooses a user's running Docker instead;
then nothing here starts or stops an engine. Called by `nodeimage`, `clusters` and the CLI.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import shutil
import subprocess
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from coral_testbed.cluster import binaries, processes
from coral_testbed.waiting import wait_for

USER_DOCKER_ENV = "CORAL_DOCKER_HOST"
CGROUP_PARENT = "coral-kind-docker"
"""The cgroup the project's dockerd puts its containers under (in every hierarchy), removed on stop."""
_CGROUP_ROOT = Path("/sys/fs/cgroup")
RUNTIME_NAME = "coral-runc"
_RUNTIME_WRAPPER = "runc-within-bounding-set"


class EngineError(RuntimeError):
    """dockerd is missing, did not start, or a docker command failed; the message says which."""


def engine_dir() -> Path:
    """The project's dockerd: data root (images), run folder (socket, pid file), log."""
    return binaries.cache_root() / "kind" / "docker"


def _run_dir() -> Path:
    # A short path: a unix socket's path is limited to 107 bytes.
    return engine_dir() / "run"


def _runtime_wrapper() -> Path:
    """The wrapper as the engine runs it: a copy in the engine's own folder, since one dockerd
    serves every checkout on the machine and must not depend on the one that started it."""
    for folder in Path(__file__).resolve().parents:
        candidate = folder / "hack" / _RUNTIME_WRAPPER
        if candidate.is_file():
            installed = _run_dir() / _RUNTIME_WRAPPER
            staged = installed.with_suffix(".new")
            shutil.copy2(candidate, staged)
            staged.replace(installed)
            return installed
    raise EngineError(f"hack/{_RUNTIME_WRAPPER} is not next to this installation (install with `make venv`)")


@dataclass(frozen=True)
class Engine:
    """A Docker engine reachable at `host`; `owned` when the project started it (and stops it)."""

    host: str
    owned: bool

    def env(self) -> dict[str, str]:
        """The environment for docker and kind: DOCKER_HOST set to this engine."""
        return {**os.environ, "DOCKER_HOST": self.host}

    def docker(
        self, *args: str, check: bool = True, input: str | None = None, timeout: float = 600
    ) -> subprocess.CompletedProcess[str]:
        """Runs the docker CLI against this engine; raises EngineError naming the command on failure."""
        docker = shutil.which("docker")
        if docker is None:
            raise EngineError("the docker CLI is missing; run `sudo bash hack/setup-docker.sh`")
        done = subprocess.run(
            [docker, *args], env=self.env(), capture_output=True, text=True, input=input, timeout=timeout
        )
        if check and done.returncode != 0:
            raise EngineError(f"docker {' '.join(args)} failed: {(done.stderr or done.stdout).strip()}")
        return done

    def is_serving(self) -> bool:
        try:
            return (
                self.docker("version", "--format", "{{.Server.Version}}", check=False, timeout=10).returncode
                == 0
            )
        except subprocess.TimeoutExpired:
            return False

    def image_exists(self, reference: str) -> bool:
        return self.docker("image", "inspect", reference, check=False).returncode == 0

    def containers(self, label_filter: str) -> list[str]:
        """Names of the containers (running or not) carrying `label_filter` (`key=value`)."""
        done = self.docker("ps", "-a", "--filter", f"label={label_filter}", "--format", "{{.Names}}")
        return done.stdout.split()


def _record() -> Path:
    return _run_dir() / "dockerd.json"


def _owned_process() -> processes.Recorded | None:
    try:
        process = processes.Recorded.from_json(json.loads(_record().read_text()))
    except (OSError, ValueError, KeyError):
        return None
    return process if processes.is_alive(process) else None


def project_engine_running() -> bool:
    """True while the project's dockerd (started by `start`) runs."""
    return _owned_process() is not None


def dockerd_argv(dockerd: str, wrapper: Path) -> list[str]:
    """The project's dockerd command line (its own socket, pid file, exec and data roots)."""
    run = _run_dir()
    return [
        dockerd,
        f"--host={project_engine().host}",
        f"--pidfile={run}/docker.pid",
        f"--exec-root={run}/exec",
        f"--data-root={engine_dir()}/data",
        "--iptables=false",
        "--ip-masq=false",
        "--ip-forward=false",
        "--bridge=none",
        f"--cgroup-parent=/{CGROUP_PARENT}",
        f"--add-runtime={RUNTIME_NAME}={wrapper}",
        f"--default-runtime={RUNTIME_NAME}",
    ]


def start(progress: Callable[[str], None]) -> Engine:
    """The engine to use: `$CORAL_DOCKER_HOST`, the project's dockerd if running, else a new one.

    Raises:
        EngineError: dockerd is not installed, or did not answer within 60 s (its log is named).
    """
    user_host = os.environ.get(USER_DOCKER_ENV)
    if user_host:
        engine = Engine(user_host, owned=False)
        if not engine.is_serving():
            raise EngineError(f"${USER_DOCKER_ENV}={user_host} does not answer")
        return engine
    with _serialized():
        return _start_owned(progress)


def project_engine() -> Engine:
    """The project's dockerd on its own socket, whether it serves or not (`start` starts it)."""
    return Engine(f"unix://{_run_dir()}/docker.sock", owned=True)


def _start_owned(progress: Callable[[str], None]) -> Engine:
    engine = project_engine()
    if _owned_process() is not None and engine.is_serving():
        return engine
    dockerd = shutil.which("dockerd")
    if dockerd is None:
        raise EngineError("dockerd is missing; run `sudo bash hack/setup-docker.sh` (Debian's docker.io)")
    _run_dir().mkdir(parents=True, exist_ok=True)
    log = engine_dir() / "dockerd.log"
    progress(f"starting the project's dockerd (log {log})")
    process = processes.spawn("dockerd", dockerd_argv(dockerd, _runtime_wrapper()), log)
    _record().write_text(json.dumps(process.to_json()))
    try:
        wait_for(
            lambda: engine.is_serving() or not processes.is_alive(process),
            timeout=60,
            message=f"dockerd on {engine.host}",
        )
    except Exception:
        _stop_owned()
        raise
    if not processes.is_alive(process):
        raise EngineError(f"dockerd exited:\n{processes.log_tail(log)}")
    return engine


@contextlib.contextmanager
def _serialized() -> Iterator[None]:
    """Held while the project's dockerd is started or stopped: two runs on one machine (a demo beside
    the tests, two checkouts) would otherwise both start one on the same socket, or one would stop
    it while the other starts it. The seconds before a run's first node container exists are
    covered by `kept_running`."""
    engine_dir().mkdir(parents=True, exist_ok=True)
    with (engine_dir() / "engine.lock").open("a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield


def stop() -> bool:
    """Stops the project's dockerd (its containers stop with it); False if it was not running."""
    with _serialized():
        return _stop_owned()


def _users_lock() -> Path:
    return engine_dir() / "users.lock"


@contextlib.contextmanager
def kept_running(node_engine: Engine, progress: Callable[[str], None]) -> Iterator[None]:
    """The project's dockerd runs, and `stop_unless` leaves it running, until the block ends.

    For a cluster's creation: until its first node container exists nothing on the engine shows
    that a run needs it, and another run ending then (the demo's cluster deleted in one lane while
    the kind folder's is made in the other) would stop it. An engine stopped between the caller's
    `start` and this block is started again. A user's Docker is left alone."""
    if not node_engine.owned:
        yield
        return
    engine_dir().mkdir(parents=True, exist_ok=True)
    # A shared lock per run: any number of runs may hold it; a stop needs it alone.
    with _users_lock().open("a") as users:
        with _serialized():
            _start_owned(progress)
            fcntl.flock(users, fcntl.LOCK_SH)
        yield


def stop_unless(in_use: Callable[[], bool]) -> bool:
    """Stops the project's dockerd unless `in_use()` or another run is inside `kept_running`, asked
    while no other run may start it; True when it was stopped."""
    with _serialized(), _users_lock().open("a") as users:
        try:
            fcntl.flock(users, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return False
        return False if in_use() else _stop_owned()


def _stop_owned() -> bool:
    process = _owned_process()
    if process is None:
        _record().unlink(missing_ok=True)
        return False
    processes.stop(process, timeout=60)
    # Only now: a stop that failed half way leaves the record, so the next stop finds the dockerd.
    _record().unlink(missing_ok=True)
    for folder in leftover_cgroups():
        # Empty once its containers are gone; rmdir refuses a cgroup that still has any.
        with contextlib.suppress(OSError):
            folder.rmdir()
    return True


def leftover_cgroups() -> list[Path]:
    """The project's dockerd's cgroup in each hierarchy, where it still exists."""
    return sorted(_CGROUP_ROOT.glob(f"*/{CGROUP_PARENT}")) + sorted(_CGROUP_ROOT.glob(CGROUP_PARENT))


def run_command(argv: Sequence[str], engine: Engine, log: Path) -> None:
    """Runs `argv` with DOCKER_HOST set to `engine`, appending its output to `log`.

    Raises:
        EngineError: the command failed; the message names it and the log.
    """
    log.parent.mkdir(parents=True, exist_ok=True)
    with log.open("a") as sink:
        sink.write(f"$ {' '.join(argv)}\n")
        sink.flush()
        code = subprocess.run(list(argv), env=engine.env(), stdout=sink, stderr=subprocess.STDOUT).returncode
    if code != 0:
        raise EngineError(f"{Path(argv[0]).name} {' '.join(argv[1:3])} failed (exit {code}); see {log}")
