"""JSON that other processes send (heartbeats, cancel requests, messages between robots, plugin
manifests, a tree's `json:` literal) is refused like any malformed message when it nests deeper
than the json module can follow, instead of raising RecursionError on a ROS thread."""

from __future__ import annotations

import pytest
from coral import bt
from coral.coordination import messages
from coral.plugins import manifest as manifests
from coral.sdk.topics import CancelRequest, Heartbeat

DEEP = "[" * 100_000 + "]" * 100_000


@pytest.mark.parametrize(
    "decode",
    [
        Heartbeat.decode,
        CancelRequest.decode,
        messages.decode_trigger,
        messages.decode_ack,
        messages.decode_value,
    ],
)
def test_a_message_nested_too_deeply_is_dropped_as_malformed(decode: object) -> None:
    assert decode(DEEP) is None  # type: ignore[operator]


def test_a_plugin_manifest_nested_too_deeply_is_refused_with_its_file() -> None:
    with pytest.raises(manifests.ManifestError, match=r"^m\.json: invalid JSON: the JSON nests too deeply"):
        manifests.parse_manifest(DEEP, "m.json")


def test_a_json_literal_nested_too_deeply_is_a_load_error() -> None:
    xml = (
        '<root BTCPP_format="4"><BehaviorTree ID="M">'
        f'<LoopString queue="json:{DEEP}" value="{{v}}"><AlwaysSuccess/></LoopString>'
        "</BehaviorTree></root>"
    )
    with pytest.raises(bt.BTLoadError, match="the JSON nests too deeply"):
        bt.load_tree_text(xml).build(bt.NodeRegistry.with_builtins())
