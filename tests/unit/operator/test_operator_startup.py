"""The operator's startup against an API server that does not answer yet."""

from __future__ import annotations

import logging
import socket
from collections.abc import Iterator
from pathlib import Path

import kopf
import pytest
import yaml
from coral_operator.handlers.settings import wait_for_the_coral_api
from coral_operator.kube import client
from kubernetes.config import kube_config


@pytest.fixture
def unreachable_api_server(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """A kubeconfig whose server is a local port nothing listens on (taken and closed again)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    server = f"https://127.0.0.1:{port}"
    kubeconfig = tmp_path / "kubeconfig"
    kubeconfig.write_text(
        yaml.safe_dump(
            {
                "apiVersion": "v1",
                "kind": "Config",
                "clusters": [
                    {"name": "gone", "cluster": {"server": server, "insecure-skip-tls-verify": True}}
                ],
                "users": [{"name": "gone", "user": {"token": "unused"}}],
                "contexts": [{"name": "gone", "context": {"cluster": "gone", "user": "gone"}}],
                "current-context": "gone",
            }
        )
    )
    # The client reads KUBECONFIG once, as it is imported.
    monkeypatch.setattr(kube_config, "KUBE_CONFIG_DEFAULT_LOCATION", str(kubeconfig))
    monkeypatch.delenv("KUBERNETES_SERVICE_HOST", raising=False)
    client.api_client.cache_clear()
    yield server
    client.api_client.cache_clear()


def test_an_api_server_that_refuses_the_first_question_is_asked_again_a_second_later(
    unreachable_api_server: str,
) -> None:
    # kopf waits a minute after an arbitrary error in a startup handler; a temporary one is retried
    # after its own delay.
    with pytest.raises(kopf.TemporaryError) as raised:
        wait_for_the_coral_api(
            settings=kopf.OperatorSettings(),
            memo=kopf.Memo(namespaces=["fleet"]),
            logger=logging.getLogger("test"),
        )
    assert raised.value.delay == 1
    assert "Waiting for the API server" in str(raised.value)
