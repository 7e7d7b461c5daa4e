"""JSON that other processes send (heartbeats, cancel requests, messages between robots, plugin
manifests, a vector port's `json:` literal) is refused like any malformed message when it nests deeper
than the json module can follow, instead of raising RecursionError on a ROS thread."""

from __future__ import annotations

import pytest
from coral.coordination import messages
from coral.plugins import manifest as manifests
from coral.sdk.topics import CancelRequest, Heartbeat
from coral_core.bt.ports import convert_string

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


def test_a_vector_ports_json_literal_nested_too_deeply_is_refused() -> None:
    # A `json:` literal is how a tree writes a std::vector port (a plugin's list port).
    with pytest.raises(ValueError, match="the JSON nests too deeply"):
        convert_string(f"json:{DEEP}", "list:int")
