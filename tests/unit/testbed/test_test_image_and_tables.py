"""The busybox test image's archive and kubectl's table output, read without a cluster."""

from __future__ import annotations

import gzip
import hashlib
import io
import json
import tarfile

from coral_testbed.cluster import nodeimages
from coral_testbed.cluster.client import parse_table


def test_the_test_image_archive_is_a_valid_oci_layout_and_reproducible() -> None:
    names = (nodeimages.TEST_IMAGE,)
    archive = nodeimages.build_archive(b"\x7fELF fake busybox", names)
    assert archive == nodeimages.build_archive(b"\x7fELF fake busybox", names)
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        members = {m.name: tar.extractfile(m).read() for m in tar.getmembers() if m.isfile()}  # type: ignore[union-attr]
    index = json.loads(members["index.json"])
    assert [m["annotations"]["io.containerd.image.name"] for m in index["manifests"]] == list(names)
    for name, data in members.items():
        if name.startswith("blobs/sha256/"):
            assert hashlib.sha256(data).hexdigest() == name.rsplit("/", 1)[1]
    manifest = json.loads(members[f"blobs/sha256/{index['manifests'][0]['digest'].split(':')[1]}"])
    layer = gzip.decompress(members[f"blobs/sha256/{manifest['layers'][0]['digest'].split(':')[1]}"])
    config = json.loads(members[f"blobs/sha256/{manifest['config']['digest'].split(':')[1]}"])
    assert config["rootfs"]["diff_ids"] == [f"sha256:{hashlib.sha256(layer).hexdigest()}"]
    with tarfile.open(fileobj=io.BytesIO(layer)) as files:
        assert files.getmember("bin/sh").linkname == "busybox"


def test_kubectl_wide_tables_are_read_by_column_position() -> None:
    table = (
        "NAME      STATUS   OS-IMAGE                         CONTAINER-RUNTIME\n"
        "robot-1   Ready    Debian GNU/Linux 12 (bookworm)   containerd://1.6.20\n"
        "kwok-1    Ready    <unknown>                        kwok-0.7.0\n"
    )
    rows = parse_table(table)
    assert rows["robot-1"]["OS-IMAGE"] == "Debian GNU/Linux 12 (bookworm)"
    assert rows["robot-1"]["CONTAINER-RUNTIME"] == "containerd://1.6.20"
    assert rows["kwok-1"]["CONTAINER-RUNTIME"] == "kwok-0.7.0"
