"""A small CoralSystem of the example skillset and an executor, for fault tests on real robots.

The system runs the images of the session's registry (`coral/examples-skillset`, `coral/executor`),
selects one robot and talks on the test's own ROS domain. Helpers read its CoralInstance and pods
the way a user would (`kubectl get coralinstance`, `kubectl get pods`).
"""

from __future__ import annotations

from typing import Any

from coral_testbed.images import catalog
from coral_testbed.missions import following
from kubernetes import client as k8s

GROUP, VERSION = "coral.dev", "v1alpha1"
SKILLSET = "examples"


def system(
    name: str,
    robot: str,
    domain: int,
    tree: str,
    *,
    startup: dict[str, Any] | None = None,
    readiness: dict[str, Any] | None = None,
    offline: dict[str, Any] | None = None,
    rollout: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The CoralSystem `name`: the example skillset (its readiness replaced by `readiness` when
    given) and an executor running `tree` on `robot`; `startup`, `offline` and `rollout` are
    the spec's fields of those names when given."""
    images = catalog.by_name()
    skillset: dict[str, Any] = {
        "name": SKILLSET,
        "image": images["examples-skillset"].reference,
        "args": ["--params", "/etc/coral/params.yaml"],
    }
    if readiness is not None:
        skillset["readiness"] = readiness
    spec: dict[str, Any] = {
        "robots": {"matchLabels": {"coral.dev/robot": robot}},
        "ros": {"domainId": domain},
        "parameters": {"inline": f"{SKILLSET}:\n  ros__parameters: {{}}\n"},
        "tree": {"tickRateHz": 10.0, "inline": tree},
        "skillsets": [skillset],
        "executors": [{"name": "executor", "image": images["executor"].reference}],
    }
    for field, value in (("startup", startup), ("offline", offline), ("rollout", rollout)):
        if value is not None:
            spec[field] = value
    return {
        "apiVersion": f"{GROUP}/{VERSION}",
        "kind": "CoralSystem",
        "metadata": {"name": name},
        "spec": spec,
    }


LONG_WAIT_TREE = """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Sequence>
      <Count count="{count}"/>
      <WaitForCount threshold="1000" timeout_ms="600000"/>
    </Sequence>
  </BehaviorTree>
</root>
"""
"""A mission that outlasts an outage: it waits on the skillset's count topic for ten minutes."""

INSPECT_OR_REPORT = """<Fallback>
        <Sequence name="Inspect">
          <Count count="{count}"/>
          <WaitForCount threshold="1000" timeout_ms="180000"/>
        </Sequence>
        <Greet name="ReportLostSkillset" who="inspection abandoned" greeting="{report}"/>
      </Fallback>"""
"""A long wait on the example skillset (its count topic) and a Fallback that reports instead, so
that a fault test can take the skillset away while a behavior of it runs."""


def mission_tree(*steps: str) -> str:
    """The tree `Main`: a Sequence of `steps` (XML elements)."""
    body = "\n      ".join(steps)
    return f"""<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Sequence>
      {body}
    </Sequence>
  </BehaviorTree>
</root>
"""


def create(custom: k8s.CustomObjectsApi, namespace: str, manifest: dict[str, Any]) -> None:
    custom.create_namespaced_custom_object(GROUP, VERSION, namespace, "coralsystems", manifest)


def delete(custom: k8s.CustomObjectsApi, namespace: str, name: str) -> None:
    custom.delete_namespaced_custom_object(GROUP, VERSION, namespace, "coralsystems", name)


def instance(custom: k8s.CustomObjectsApi, namespace: str, system_name: str) -> dict[str, Any]:
    """The system's only CoralInstance, or {} while there is none."""
    items = custom.list_namespaced_custom_object(GROUP, VERSION, namespace, "coralinstances")["items"]
    return next((i for i in items if i["spec"]["system"] == system_name), {})


def with_root(custom: k8s.CustomObjectsApi, namespace: str, system_name: str, *roots: str) -> dict[str, Any]:
    """The system's CoralInstance once its tree's root status is one of `roots`, else {}."""
    item = instance(custom, namespace, system_name)
    return item if tree(item).get("rootStatus") in roots else {}


def condition(item: dict[str, Any], kind: str) -> dict[str, Any]:
    return following.condition(item, kind)


def tree(item: dict[str, Any]) -> dict[str, Any]:
    return following.tree(item)


def pods(core: k8s.CoreV1Api, namespace: str, system_name: str, component: str | None = None) -> list[Any]:
    """The system's pods (of one component when given)."""
    selector = f"coral.dev/system={system_name}"
    if component is not None:
        selector += f",coral.dev/component={component}"
    return core.list_namespaced_pod(namespace, label_selector=selector).items


def container_id(status: Any) -> str:
    """The runtime's ID of a container (`containerd://ID` in the pod status), or '' before it ran."""
    return (status.container_id or "").rpartition("://")[2]
