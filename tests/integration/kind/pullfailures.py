"""One pull failure on a kind robot, from the user's side: the CoralInstance names it, then tells the
recovery once the cause is gone; and the robot's own way to its registry refused or diverted.

The image that fails is the operator's helper image, which the plugin-folder init step of every
component pod runs (issue 50: the pods said `ImagePullBackOff` there while the instance said only
`HealthTimeout`); the chart's `helperImage` names it (the operator's own image by default).

A robot reaches the cluster's registry at the address its containerd knows as plain HTTP (the
network's gateway, `clusters.py`). The faults here act in the robot's node container only, in its
own network namespace, as a firewall on the robot would: the host's rules are never touched.
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from collections.abc import Callable, Iterator
from typing import Any

from coral_operator.planning.pods import FOLDERS_OWNER
from coral_testbed.cluster import operatorchart
from coral_testbed.kind import clusters
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s
from missions import realsystems as rs

from .fleet import on_robot

ROBOT = "relay-worker"
"""The robot the pull failures happen on."""

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


def _events(core: k8s.CoreV1Api, namespace: str, instance: dict[str, Any]) -> list[Any]:
    """The Events of this very instance: an earlier test's instance of the same name, in the same
    namespace, has Events of its own."""
    selector = f"involvedObject.uid={instance['metadata']['uid']},involvedObject.kind=CoralInstance"
    return core.list_namespaced_event(namespace, field_selector=selector).items


def _pull_failed(custom: k8s.CustomObjectsApi, namespace: str) -> dict[str, Any]:
    item = rs.instance(custom, namespace, SYSTEM)
    return item if rs.condition(item, "ComponentsReady").get("reason") == "ImagePullFailed" else {}


def named_then_recovered(
    missions: KindMissionStack,
    *,
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
    core, custom, namespace = missions.core, missions.custom, missions.namespace
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
    warned = wait_for(
        lambda: [e for e in _events(core, namespace, item) if e.reason == "ImagePullFailed"],
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
        lambda: [e for e in _events(core, namespace, item) if e.reason == "Recovered"],
        timeout=30,
        message="a Normal Event telling the recovery",
    )
    assert told[0].type == "Normal" and told[0].message.startswith("No longer ImagePullFailed"), told[0]
    rs.delete(custom, namespace, SYSTEM)


def _rule_switch(
    running: clusters.Running, robot: str, table: str, chain: str, rule: list[str]
) -> Iterator[Callable[[], None]]:
    """Adds `rule` at the head of `chain` in the robot's own network namespace; yields a call that
    takes it away again (also done on the way out, once)."""
    on_robot(running, robot, "iptables", "-w", "-t", table, "-I", chain, "1", *rule)
    present = [True]

    def remove() -> None:
        if present[0]:
            on_robot(running, robot, "iptables", "-w", "-t", table, "-D", chain, *rule)
            present[0] = False

    try:
        yield remove
    finally:
        remove()


def _registry_rule(running: clusters.Running) -> list[str]:
    host, _, port = running.registry_address.rpartition(":")
    return ["-p", "tcp", "-d", host, "--dport", port]


@contextlib.contextmanager
def registry_refused(running: clusters.Running, robot: str) -> Iterator[Callable[[], None]]:
    """The robot's connections to the cluster's registry are refused (a TCP reset, as from a port
    where nothing listens); call the result to let them through again."""
    rule = [*_registry_rule(running), "-j", "REJECT", "--reject-with", "tcp-reset"]
    yield from _rule_switch(running, robot, "filter", "OUTPUT", rule)


@contextlib.contextmanager
def registry_diverted(running: clusters.Running, robot: str, port: int) -> Iterator[Callable[[], None]]:
    """The robot's new connections to the cluster's registry go to `port` of the registry's host
    (the network's gateway) instead; call the result to end that."""
    host = running.registry_address.rpartition(":")[0]
    rule = [*_registry_rule(running), "-j", "DNAT", "--to-destination", f"{host}:{port}"]
    yield from _rule_switch(running, robot, "nat", "OUTPUT", rule)


@contextlib.contextmanager
def chart_helper_image(missions: KindMissionStack, image: str) -> Iterator[str]:
    """`helm upgrade` of the chart's operator with `helperImage` = `image`, as a user names a
    helper image of their own; the chart's default again on the way out, once no pod of the
    test's systems is left and the image's name is taken off `ROBOT` (the next test finds the
    robot as this one did)."""
    release = missions.release
    assert missions.cluster.bin_dir is not None
    helm, env, api = missions.cluster.bin_dir / "helm", missions.cluster.env(), missions.cluster.api_client
    operatorchart.upgrade(api, helm, env, dataclasses.replace(release, helper_image=image))
    try:
        yield image
    finally:
        missions.delete_systems()
        operatorchart.upgrade(api, helm, env, release)
        on_robot(missions.running, ROBOT, "crictl", "rmi", image, check=False)
