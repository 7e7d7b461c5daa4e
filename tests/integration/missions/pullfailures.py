"""One pull failure on a real robot, from the user's side: the CoralInstance names it, then tells the
recovery once the cause is gone.

The image that fails is the operator's helper image, which the plugin-folder init step of every
component pod runs (issue 50: the pods said `ImagePullBackOff` there while the instance said only
`HealthTimeout`); each test names it where its fault applies (`CORAL_HELPER_IMAGE`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from coral_operator.planning.pods import FOLDERS_OWNER
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s

from . import realsystems as rs

SYSTEM = "unpulled"
TREE = """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Count count="{count}"/>
  </BehaviorTree>
</root>
"""
NAMED_WITHIN_S = 30
RECOVERY_S = 180
"""From the cure to the mission's SUCCESS. The kubelet's back-off between pulls of one image starts
at 10 s and doubles with each failure (up to 5 minutes); the cure comes as soon as the failure is
named and warned about (within 60 s of the first pod), so at most three pulls have failed and the
next one comes within 40 s, plus the kubelet's resync. The rest is that pull, the mission's own
images on a robot that never ran it (some 700 MB: up to a minute on a busy host) and the mission."""


def _events(core: k8s.CoreV1Api, namespace: str, instance: str) -> list[Any]:
    selector = f"involvedObject.name={instance},involvedObject.kind=CoralInstance"
    return core.list_namespaced_event(namespace, field_selector=selector).items


def _pull_failed(custom: k8s.CustomObjectsApi, namespace: str) -> dict[str, Any]:
    item = rs.instance(custom, namespace, SYSTEM)
    return item if rs.condition(item, "ComponentsReady").get("reason") == "ImagePullFailed" else {}


def named_then_recovered(
    *,
    core: k8s.CoreV1Api,
    custom: k8s.CustomObjectsApi,
    namespace: str,
    robot: str,
    domain: int,
    image: str,
    cause: str,
    cure: Callable[[], None],
) -> None:
    """Runs a mission on `robot` while `image` cannot be pulled there: within 30 s of the first pod
    the instance says `ImagePullFailed` with the kubelet's message (naming the init step, `image`
    and `cause`), without being Stalled, and a Warning Event says it; after `cure()` the kubelet's
    back-off pulls the image, the mission succeeds, `ComponentsReady` turns True and a Normal Event
    tells the recovery."""
    rs.create(custom, namespace, rs.system(SYSTEM, robot, domain, TREE))
    wait_for(lambda: rs.pods(core, namespace, SYSTEM), timeout=60, message="the first component pod")
    created = time.monotonic()
    item = wait_for(
        lambda: _pull_failed(custom, namespace),
        timeout=NAMED_WITHIN_S,
        interval=0.5,
        message=lambda: f"ImagePullFailed within 30 s: {rs.instance(custom, namespace, SYSTEM)}",
    )
    components = rs.condition(item, "ComponentsReady")
    assert f"container {FOLDERS_OWNER}:" in components["message"], components
    assert image in components["message"], "the kubelet's message names the image"
    assert cause in components["message"], f"the kubelet's message says {cause!r}: {components}"
    assert rs.condition(item, "Stalled")["status"] == "False", "the kubelet keeps trying"
    instance = item["metadata"]["name"]
    warned = wait_for(
        lambda: [e for e in _events(core, namespace, instance) if e.reason == "ImagePullFailed"],
        timeout=30,
        message="a Warning Event on the instance",
    )
    assert warned[0].type == "Warning" and image in warned[0].message
    print(f"ImagePullFailed on the instance {time.monotonic() - created:.1f} s after its first pod")

    cure()
    cured = time.monotonic()
    wait_for(
        lambda: rs.with_root(custom, namespace, SYSTEM, "SUCCESS"),
        timeout=RECOVERY_S,
        interval=1,
        message=lambda: (
            f"the mission to run once the image can be pulled: {rs.instance(custom, namespace, SYSTEM)}"
        ),
    )
    print(f"the mission succeeded {time.monotonic() - cured:.1f} s after the cause was gone")
    # The executor writes the root's SUCCESS itself; the operator's next pass tells ComponentsReady.
    wait_for(
        lambda: (
            rs.condition(rs.instance(custom, namespace, SYSTEM), "ComponentsReady").get("status") == "True"
        ),
        timeout=30,
        interval=0.5,
        message=lambda: f"ComponentsReady=True after the pull: {rs.instance(custom, namespace, SYSTEM)}",
    )
    told = wait_for(
        lambda: [e for e in _events(core, namespace, instance) if e.reason == "Recovered"],
        timeout=30,
        message="a Normal Event telling the recovery",
    )
    assert told[0].type == "Normal" and told[0].message.startswith("No longer ImagePullFailed"), told[0]
    rs.delete(custom, namespace, SYSTEM)
