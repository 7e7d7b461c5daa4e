"""An API request's Kubernetes verb and resource, from its method and URL (the way the API server's
request info reads them), so that requests can be counted by kind without a label per object."""

from __future__ import annotations

from urllib.parse import urlsplit

_WRITE_VERBS = {"POST": "create", "PUT": "update", "PATCH": "patch"}


def request_info(method: str, url: str) -> tuple[str, str]:
    """(verb, resource) of a request: `get`/`list`/`create`/`update`/`patch`/`delete`/
    `deletecollection`, and the resource's plural with its subresource (`coralinstances/status`).

    A path outside the resource API (`/version`, `/openapi/v3`) is resource `other`.
    """
    parts = [part for part in urlsplit(url).path.split("/") if part]
    if parts[:1] == ["api"]:
        rest = parts[2:]
    elif parts[:1] == ["apis"]:
        rest = parts[3:]
    else:
        return method.lower(), "other"
    # `namespaces/NS/RESOURCE...` names a namespaced resource; `namespaces` and `namespaces/NS`
    # alone are the Namespace objects themselves.
    if len(rest) >= 3 and rest[0] == "namespaces":
        rest = rest[2:]
    if not rest:
        return method.lower(), "other"
    resource = rest[0] + (f"/{rest[2]}" if len(rest) >= 3 else "")
    named = len(rest) >= 2
    upper = method.upper()
    if upper == "GET":
        verb = "get" if named else "list"
    elif upper == "DELETE":
        verb = "delete" if named else "deletecollection"
    else:
        verb = _WRITE_VERBS.get(upper, method.lower())
    return verb, resource
