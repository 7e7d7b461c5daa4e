"""The control-plane binaries are the pinned versions, and Python agrees with the build script on them."""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import pytest
from coral_testbed.cluster import Cluster, binaries

SCRIPT = Path(__file__).resolve().parents[3] / "hack" / "build-control-plane.sh"


def _script_default(name: str) -> str:
    match = re.search(rf'^{name}="\$\{{{name}:-([^}}]+)\}}"', SCRIPT.read_text(), re.MULTILINE)
    assert match, f"{SCRIPT}: no default for {name}"
    return match.group(1)


def test_python_pins_match_the_build_script() -> None:
    assert binaries.KUBE_VERSION == _script_default("KUBE_VERSION")
    assert binaries.ETCD_VERSION == _script_default("ETCD_VERSION")
    assert binaries.KWOK_VERSION == _script_default("KWOK_VERSION")
    assert binaries.HELM_VERSION == _script_default("HELM_VERSION")


@pytest.mark.cluster
def test_kubectl_and_the_api_server_are_the_pinned_kubernetes(cluster: Cluster) -> None:
    versions = json.loads(cluster.kubectl("version", "-o", "json").stdout)
    if cluster.bin_dir is not None:
        assert versions["clientVersion"]["gitVersion"] == binaries.KUBE_VERSION
    if cluster.is_local:
        assert versions["serverVersion"]["gitVersion"] == binaries.KUBE_VERSION
        for name, version in (("etcd", binaries.ETCD_VERSION), ("kwok", binaries.KWOK_VERSION)):
            out = subprocess.run(
                [str(cluster.bin_dir / name), "--version"], capture_output=True, text=True
            ).stdout
            assert version.lstrip("v") in out, out
