"""A kind robot whose disk is full while it pulls an image, for the init step that owns the plugin folder.

Issue 50: with the disk full mid-pull, the pods said `ImagePullBackOff` for that init step while the
CoralInstance said only `HealthTimeout`. The full disk here is a real one: the robot's image store
(containerd's content store, where a pull writes every blob it fetches) is given a small filesystem
of its own inside the robot's node (its own mount namespace), a 16 MiB tmpfs under an overlay that
keeps every blob the robot already has, and that filesystem is filled to its last 256 KiB. The
helper image is one the robot never had: the operator's image with one more layer of random bytes,
pushed to the cluster's registry and made the chart's `helperImage` by `helm upgrade`. The robot
has the operator's image and the mission's before its disk fills, so the new image's manifest and
config land and its new layer does not ("no space left on device"). The instance must say
`ImagePullFailed` with the kubelet's message within 30 s; the disk is then freed at once, the
kubelet's back-off pulls the image, the mission runs and the instance tells the recovery
(`pullfailures`). The chart's helper and the robot's store are put back afterwards.
"""

from __future__ import annotations

import gzip
import hashlib
import io
import json
import os
import tarfile
from collections.abc import Callable, Iterator

import pytest
from coral_testbed.cluster import operatorchart
from coral_testbed.images import registry
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.waiting import wait_for
from missions import realsystems as rs

from . import pullfailures
from .fleet import on_robot, pull_for

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(900)]

ROBOT = pullfailures.ROBOT
CONTENT = "/var/lib/containerd/io.containerd.content.v1.content"
"""containerd's content store on the robot: every blob a pull fetches is written here first."""
DISK = "/var/lib/containerd/full-disk"
"""Where the small filesystem is mounted, in the robot's own mount view."""
DISK_SIZE = "16m"
LEFT_FREE = 256 * 1024
"""Room left on the full disk: a manifest and a config fit, the new layer does not."""
LAYER_BYTES = 4 * 1024 * 1024


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
def helper_image(kind_operator: KindMissionStack) -> Iterator[str]:
    """The operator's image with one more layer, as robots name it (no robot has it yet), made the
    chart's `helperImage`; the chart's default again afterwards."""
    repository, tag = operatorchart.operator_image()
    path = repository.removeprefix(operatorchart.ROBOT_REGISTRY + "/")
    new_tag = f"{tag}-full-disk-{os.urandom(4).hex()}"
    push_with_one_more_layer(kind_operator.running.registry_address, path, tag, new_tag)
    with pullfailures.chart_helper_image(kind_operator, f"{repository}:{new_tag}") as image:
        yield image


def _inside(kind_operator: KindMissionStack, script: str) -> str:
    """Runs `script` in the robot's node (its mounts are the robot's alone)."""
    return on_robot(kind_operator.running, ROBOT, "sh", "-ec", script)


@pytest.fixture
def full_disk(kind_operator: KindMissionStack, helper_image: str) -> Iterator[Callable[[], None]]:
    """Fills the robot's image store; call the result to free it (the filler is deleted).

    At teardown the blobs written meanwhile are kept (copied to the robot's own disk, so its
    runtime's records stay true) and the small filesystem goes.
    """
    # The mission's images and the one the new helper extends are on the robot before its disk
    # fills, as on a robot in the field that runs Coral already: then only the new layer needs
    # room. A robot without them would have to fetch hundreds of MB into the small filesystem,
    # which no freeing makes room for, and recovery could never be seen.
    pull_for(kind_operator, [ROBOT], rs.system(pullfailures.SYSTEM, ROBOT, 0, pullfailures.TREE))
    _inside(
        kind_operator,
        f"mkdir -p {DISK} && mount -t tmpfs -o size={DISK_SIZE},mode=0700 coral-full-disk {DISK} && "
        f"mkdir {DISK}/upper {DISK}/work && "
        f"mount -t overlay coral-full-disk -o lowerdir={CONTENT},upperdir={DISK}/upper,workdir={DISK}/work "
        f"{CONTENT} && "
        f'free=$(( $(stat -f -c "%a*%S" {DISK}) )) && fallocate -l $(( free - {LEFT_FREE} )) {DISK}/filler',
    )
    try:
        yield lambda: _inside(kind_operator, f"rm {DISK}/filler")
    finally:
        # Once the overlay is gone the robot's own store shows again; the blobs pulled meanwhile
        # (whiteouts are not files) join it, so its runtime's records stay true.
        _inside(
            kind_operator,
            f"umount --lazy {CONTENT} && cd {DISK}/upper && "
            f"if [ -d blobs ]; then find blobs -type f -exec cp -p -n --parents {{}} {CONTENT}/ \\; ; fi && "
            f"cd / && umount --lazy {DISK} && rmdir {DISK}",
        )


def test_a_full_disk_during_the_pull_of_the_plugin_folder_step_is_named_and_its_recovery_told(
    kind_operator: KindMissionStack,
    helper_image: str,
    full_disk: Callable[[], None],
    ros_env: dict[str, str],
) -> None:
    pullfailures.named_then_recovered(
        kind_operator,
        robot=ROBOT,
        domain=int(ros_env["ROS_DOMAIN_ID"]),
        image=helper_image,
        cause="no space left on device",
        cure=full_disk,
    )
    wait_for(
        lambda: not rs.pods(kind_operator.core, kind_operator.namespace, pullfailures.SYSTEM),
        timeout=120,
        message="the system's pods to go before the robot's image store is put back",
    )
