"""`coral.sdk` keeps its documented public names; other components build on them."""

from __future__ import annotations

import subprocess
import sys

import coral.sdk

DOCUMENTED = {
    "Component",
    "Skillset",
    "Driver",
    "CancelToken",
    "behavior",
    "input_port",
    "output_port",
    "inout_port",
    "ServiceCall",
    "LatestMessage",
    "TopicWait",
    "publisher",
    "ServiceBehavior",
    "run_component",
}


def test_every_documented_name_is_exported_and_resolves() -> None:
    assert set(coral.sdk.__all__) == DOCUMENTED
    for name in coral.sdk.__all__:
        assert getattr(coral.sdk, name) is not None, name


def test_importing_the_sdk_for_declarations_does_not_import_rclpy() -> None:
    probe = (
        "import sys, coral.sdk, coral.sdk.declaring, coral.plugins.discovery; print('rclpy' in sys.modules)"
    )
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60)
    assert result.stdout.strip() == "False", result.stderr
