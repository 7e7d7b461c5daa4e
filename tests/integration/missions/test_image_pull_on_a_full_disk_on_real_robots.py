"""A robot whose disk is full while it pulls an image, for the init step that owns the plugin folder.

Issue 50: with the disk full mid-pull, the pods said `ImagePullBackOff` for that init step while the
CoralInstance said only `HealthTimeout`. The full disk here is a real one: the robot's image store
(containerd's content store, where a pull writes every blob it fetches) is given a small filesystem
of its own, a 16 MiB tmpfs under an overlay that keeps every blob the robot already has, and that
filesystem is filled to its last 256 KiB. The helper image is one the robot never had: the
operator's image with one more layer of random bytes, pushed to the session's registry. The robot
has the operator's image and the mission's before its disk fills, so the new image's manifest and
config land and its new layer does not ("no space left on device"). The instance must say
`ImagePullFailed` with the kubelet's message within 30 s; the disk is then freed at once, the kubelet's
back-off pulls the image, the mission runs and the instance tells the recovery (`pullfailures`).
"""

from __future__ import annotations

import gzip
import hashlib
import io
import json
import os
import subprocess
import tarfile
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from coral_testbed.cluster import Cluster, operatorchart, realrobots
from coral_testbed.images import registry
from coral_testbed.waiting import wait_for
from fixtures.operator import OperatorProcess
from fixtures.robots import REAL_ROBOT_MARKS
from kubernetes import client as k8s

from . import pullfailures
from . import realsystems as rs
from .conftest import first_real_robot

# The first test of a session also starts the robots; the base image's pull has its own bound.
pytestmark = [*REAL_ROBOT_MARKS, pytest.mark.timeout(600)]

CONTENT = "/var/lib/containerd/io.containerd.content.v1.content"
"""containerd's content store on the robot: every blob a pull fetches is written here first."""
DISK = "/var/lib/containerd/full-disk"
"""Where the small filesystem is mounted, in the robot's own mount view."""
DISK_SIZE = "16m"
LEFT_FREE = 256 * 1024
"""Room left on the full disk: a manifest and a config fit, the new layer does not."""
LAYER_BYTES = 4 * 1024 * 1024
BASE_PULL_S = 180
"""One of those images (400 to 700 MB unpacked) from the session's registry, on a busy host."""


def _random_layer() -> tuple[bytes, str]:
    """A gzip tar holding one file of random bytes (no two runs share it), and its diff ID."""
    data = os.urandom(LAYER_BYTES)
    tar = io.BytesIO()
    with tarfile.open(fileobj=tar, mode="w") as archive:
        entry = tarfile.TarInfo("coral-full-disk-test")
        entry.size = len(data)
        archive.addfile(entry, io.BytesIO(data))
    plain = tar.getvalue()
    return gzip.compress(plain, compresslevel=1), "sha256:" + hashlib.sha256(plain).hexdigest()


def push_with_one_more_layer(address: str, repository: str, tag: str, new_tag: str) -> None:
    """Pushes `repository:new_tag`: `repository:tag` with one more layer of random bytes."""
    manifest = registry.manifest_document(address, repository, tag)
    assert manifest is not None and manifest.get("layers"), f"{repository}:{tag} is no single image"
    config = registry.image_config(address, repository, manifest["config"]["digest"])
    layer, diff_id = _random_layer()
    config["rootfs"]["diff_ids"].append(diff_id)
    if "history" in config:
        config["history"].append({"created_by": "coral full-disk test layer"})
    config_bytes = json.dumps(config).encode()
    manifest["config"] |= {
        "digest": registry.put_blob(address, repository, config_bytes),
        "size": len(config_bytes),
    }
    manifest["layers"].append(
        {
            "mediaType": manifest["layers"][-1]["mediaType"],
            "digest": registry.put_blob(address, repository, layer),
            "size": len(layer),
        }
    )
    media_type = manifest.get("mediaType") or "application/vnd.docker.distribution.manifest.v2+json"
    registry.put_manifest(address, repository, new_tag, manifest, media_type)


@pytest.fixture
def helper_image(image_registry: str, built_images: dict[str, Any]) -> str:
    """The operator's image with one more layer, as robots name it; no robot has it yet."""
    repository, tag = operatorchart.operator_image()
    path = repository.removeprefix(operatorchart.ROBOT_REGISTRY + "/")
    new_tag = f"{tag}-full-disk-{os.urandom(4).hex()}"
    push_with_one_more_layer(image_registry, path, tag, new_tag)
    return f"{repository}:{new_tag}"


@pytest.fixture
def operator_env(helper_image: str) -> dict[str, str]:
    return {"CORAL_HELPER_IMAGE": helper_image}


def _inside(robots: realrobots.RealRobots, robot: str, script: str) -> str:
    """Runs `script` in the robot's own mount view (the mounts it makes are the robot's alone)."""
    done = subprocess.run(
        [*robots.enter(robot), "sh", "-ec", script], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 0, f"on {robot}: {script}\n{done.stderr}"
    return done.stdout


def _images_already_there(robot: str) -> list[str]:
    """The operator's image and the images of the mission `pullfailures` runs."""
    repository, tag = operatorchart.operator_image()
    spec = rs.system(pullfailures.SYSTEM, robot, 0, pullfailures.TREE)["spec"]
    return [f"{repository}:{tag}", *(c["image"] for c in [*spec["skillsets"], *spec["executors"]])]


@pytest.fixture
def full_disk(real_robots: realrobots.RealRobots, namespace: str) -> Iterator[Callable[[], None]]:
    """Fills the first robot's image store; call the result to free it (the filler is deleted).

    At teardown the blobs written meanwhile are kept (copied to the robot's own disk, so its
    runtime's records stay true) and the small filesystem goes.
    """
    robot = first_real_robot(real_robots)
    # The mission's images and the one the new helper extends are on the robot before its disk
    # fills, as on a robot in the field that runs Coral already: then only the new layer needs
    # room. A robot without them would have to fetch hundreds of MB into the small filesystem,
    # which no freeing makes room for, and recovery could never be seen.
    for image in _images_already_there(robot):
        real_robots.cri(robot, "pull", image, timeout=BASE_PULL_S)
    _inside(
        real_robots,
        robot,
        f"mkdir -p {DISK} && mount -t tmpfs -o size={DISK_SIZE},mode=0700 coral-full-disk {DISK} && "
        f"mkdir {DISK}/upper {DISK}/work && "
        f"mount -t overlay coral-full-disk -o lowerdir={CONTENT},upperdir={DISK}/upper,workdir={DISK}/work "
        f"{CONTENT} && "
        f'free=$(( $(stat -f -c "%a*%S" {DISK}) )) && fallocate -l $(( free - {LEFT_FREE} )) {DISK}/filler',
    )
    try:
        yield lambda: _inside(real_robots, robot, f"rm {DISK}/filler")
    finally:
        # Once the overlay is gone the robot's own store shows again; the blobs pulled meanwhile
        # (whiteouts are not files) join it, so its runtime's records stay true.
        _inside(
            real_robots,
            robot,
            f"umount --lazy {CONTENT} && cd {DISK}/upper && "
            f"if [ -d blobs ]; then find blobs -type f -exec cp -p -n --parents {{}} {CONTENT}/ \\; ; fi && "
            f"cd / && umount --lazy {DISK} && rmdir {DISK}",
        )


def test_a_full_disk_during_the_pull_of_the_plugin_folder_step_is_named_and_its_recovery_told(
    cluster: Cluster,
    namespace: str,
    built_images: dict[str, Any],
    real_robots: realrobots.RealRobots,
    helper_image: str,
    full_disk: Callable[[], None],
    coral_operator: OperatorProcess,
    ros_env: dict[str, str],
) -> None:
    core = k8s.CoreV1Api(cluster.api_client)
    robot = first_real_robot(real_robots)
    pullfailures.named_then_recovered(
        core=core,
        custom=k8s.CustomObjectsApi(cluster.api_client),
        namespace=namespace,
        robot=robot,
        domain=int(ros_env["ROS_DOMAIN_ID"]),
        image=helper_image,
        cause="no space left on device",
        cure=full_disk,
    )
    wait_for(
        lambda: not rs.pods(core, namespace, pullfailures.SYSTEM),
        timeout=120,
        message="the system's pods to go before the robot's image store is put back",
    )
