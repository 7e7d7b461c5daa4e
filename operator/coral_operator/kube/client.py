"""The shared Kubernetes API client of the operator process (in-cluster or from KUBECONFIG).

Used by `kube.applying` and `kube.reading`; one client per process, created on first use.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import urllib3
from coral_core import names
from kubernetes import client, config
from kubernetes.client.exceptions import ApiException
from kubernetes.config.config_exception import ConfigException

CONNECTIONS = 64
"""Pooled connections to the API server: more than the handler threads plus the parallel writers."""

NO_ANSWER: tuple[type[Exception], ...] = (ApiException, urllib3.exceptions.HTTPError, OSError)
"""What a call raises when the API server gave no usable answer: an error status, a timeout, a
refused or dropped connection."""


@functools.cache
def api_client() -> client.ApiClient:
    """The process-wide API client; in-cluster configuration first, then KUBECONFIG."""
    configuration = client.Configuration()
    try:
        config.load_incluster_config(client_configuration=configuration)
    except ConfigException:
        config.load_kube_config(client_configuration=configuration)
    # Handler threads and `applying.in_parallel` call concurrently; with urllib3's default of 10
    # pooled connections the rest are opened and discarded per request, each a new TLS handshake,
    # which at a thousand robots costs more CPU than the requests themselves.
    configuration.connection_pool_maxsize = CONNECTIONS
    api = client.ApiClient(configuration)
    # Named in audit logs and, as the field manager of every write, in managedFields (the client's
    # default is "OpenAPI-Generator", which says nothing about who wrote).
    api.user_agent = names.MANAGER
    return api


def core() -> client.CoreV1Api:
    return client.CoreV1Api(api_client())


def rbac() -> client.RbacAuthorizationV1Api:
    return client.RbacAuthorizationV1Api(api_client())


def admission() -> client.AdmissionregistrationV1Api:
    return client.AdmissionregistrationV1Api(api_client())


def custom() -> client.CustomObjectsApi:
    return client.CustomObjectsApi(api_client())


def load_api_classes() -> None:
    """Import the client's API classes now: each is a module of thousands of lines imported on first
    use, and a fleet's first pass would otherwise stall on them (0.8 s of CPU under the GIL)."""
    for build in (core, rbac, admission, custom):
        build()


def count_requests(record: Callable[[str, str, int], None]) -> None:
    """Tell `record(method, url, code)` of every request the process's client makes (code 0: no
    answer), for the operator's metrics. Call once."""
    api = api_client()
    call = api.call_api

    def counted(method: str, url: str, *args: Any, **kwargs: Any) -> Any:
        try:
            response = call(method, url, *args, **kwargs)
        except ApiException as error:
            record(method, url, int(error.status or 0))
            raise
        except Exception:
            record(method, url, 0)
            raise
        record(method, url, int(response.status))
        return response

    api.call_api = counted  # type: ignore[method-assign]


def post(path: str, body: dict[str, Any]) -> bytes:
    """POST `body` as JSON to the API path `path`; the answer's bytes. Raises `ApiException` for
    an answer other than 2xx, as the typed calls do.

    For the writes a fleet makes by the thousand: the typed calls first validate a plain dict into
    the client's models and serialize those back (a pod: about a third of a millisecond of CPU,
    several percent of the operator's time at 1000 robots), to send the same JSON.
    """
    api = api_client()
    method, url, headers, _, _ = api.param_serialize(
        method="POST",
        resource_path=path,
        header_params={"Content-Type": "application/json", "Accept": "application/json"},
        auth_settings=["BearerToken"],
    )
    response = api.call_api(method, url, header_params=headers, body=body)
    data = response.read()
    if not 200 <= response.status <= 299:
        raise ApiException.from_response(http_resp=response, body=None, data=None)
    return bytes(data or b"")
