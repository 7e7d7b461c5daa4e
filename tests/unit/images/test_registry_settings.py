"""The local registry's configuration and addresses."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from coral_testbed.images import registry


def test_the_configuration_listens_where_asked_and_stores_in_the_given_folder() -> None:
    config = json.loads(registry.render_config("127.0.0.1:5123", Path("/cache/registry")))
    assert config["http"]["addr"] == "127.0.0.1:5123"
    assert config["storage"]["filesystem"]["rootdirectory"] == "/cache/registry"


@pytest.mark.parametrize("address", ["127.0.0.1", ":5000", "127.0.0.1:port", "127.0.0.1:70000"])
def test_a_bad_address_is_refused_by_name(address: str) -> None:
    with pytest.raises(ValueError, match=f"registry address '{address}' is not HOST:PORT"):
        registry.split_address(address)


def test_a_free_address_is_on_loopback() -> None:
    host, port = registry.split_address(registry.free_address())
    assert host == "127.0.0.1" and port > 0
