"""The privilege policy, one table: what the default refuses, what an opened namespace may do.

Every row is a change to a valid spec, the namespace it is created in, the operator's policy
environment, and the problems the operator must report (empty: allowed).
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import pytest
from coral_operator import config
from coral_operator.api.system import CoralSystemSpec
from coral_operator.planning import policy
from operator_specs import BASE_SPEC

OPEN_NETWORK = {"CORAL_POLICY_HOST_NETWORK_NAMESPACES": "robots"}
POD_NETWORK = {"ros": {"network": "Pod"}}


def _driver(**fields: Any) -> Callable[[dict[str, Any]], None]:
    def change(spec: dict[str, Any]) -> None:
        spec["drivers"][0].update(fields)

    return change


def _mount(host_path: str, at: str = "/x", **more: Any) -> Callable[[dict[str, Any]], None]:
    """The driver mounts `host_path` at `at`."""
    return _driver(hostPaths=[{"hostPath": host_path, "mountPath": at, **more}])


def _spec(**top: Any) -> Callable[[dict[str, Any]], None]:
    def change(spec: dict[str, Any]) -> None:
        spec.update(copy.deepcopy(top))

    return change


def _nothing(spec: dict[str, Any]) -> None:
    pass


DEVICES = "(/dev/ttyUSB*, /dev/ttyACM*, /dev/video*)"
OUTSIDE = "is outside the folders namespace robots may mount (/var/lib/coral/data/robots)"
HOST_NET_DENIED = "spec.ros.network: the host network (Host) is not allowed in namespace robots; use Pod"


def _outside(host_path: str) -> list[str]:
    """The one problem of a driver mounting `host_path` (as the policy spells it) outside those folders."""
    return [f"spec.drivers[0] (lidar): hostPaths[0].hostPath: host path {host_path} {OUTSIDE}"]


ROWS: list[tuple[str, Callable[[dict[str, Any]], None], dict[str, str], list[str]]] = [
    ("pod network needs nothing", _spec(**POD_NETWORK), {}, []),
    ("host network is closed by default", _nothing, {}, [HOST_NET_DENIED]),
    ("host network opened for the namespace", _nothing, OPEN_NETWORK, []),
    ("host network opened for every namespace", _nothing, {"CORAL_POLICY_HOST_NETWORK_NAMESPACES": "*"}, []),
    (
        "host network opened elsewhere only",
        _nothing,
        {"CORAL_POLICY_HOST_NETWORK_NAMESPACES": "lab"},
        [HOST_NET_DENIED],
    ),
    (
        "privileged driver by default",
        _driver(privileged=True),
        OPEN_NETWORK,
        ["spec.drivers[0] (lidar): privileged is not allowed in namespace robots"],
    ),
    (
        "privileged driver in an opened namespace",
        _driver(privileged=True),
        {**OPEN_NETWORK, "CORAL_POLICY_PRIVILEGED_NAMESPACES": "robots"},
        [],
    ),
    (
        "runAsRoot by default",
        _driver(runAsRoot=True),
        OPEN_NETWORK,
        ["spec.drivers[0] (lidar): runAsRoot is not allowed in namespace robots"],
    ),
    (
        "runAsRoot in an opened namespace",
        _driver(runAsRoot=True),
        {**OPEN_NETWORK, "CORAL_POLICY_ROOT_NAMESPACES": "robots"},
        [],
    ),
    (
        "hostPath / by default",
        _mount("/", at="/host", readOnly=False),
        OPEN_NETWORK,
        _outside("/"),
    ),
    (
        "a .. path climbing out of the namespace's own folder",
        _mount("/var/lib/coral/data/robots/../../../../../etc"),
        OPEN_NETWORK,
        _outside("/etc"),
    ),
    (
        "a .. path climbing into another namespace's folder",
        _mount("/var/lib/coral/data/robots/../lab/maps"),
        OPEN_NETWORK,
        _outside("/var/lib/coral/data/lab/maps"),
    ),
    (
        "another namespace's data folder",
        _mount("/var/lib/coral/data/lab"),
        OPEN_NETWORK,
        _outside("/var/lib/coral/data/lab"),
    ),
    (
        "the data root holding every namespace's folder",
        _mount("/var/lib/coral/data"),
        OPEN_NETWORK,
        _outside("/var/lib/coral/data"),
    ),
    (
        "a look-alike of the namespace's folder is not the folder",
        _mount("/var/lib/coral/data/robotsx"),
        OPEN_NETWORK,
        _outside("/var/lib/coral/data/robotsx"),
    ),
    (
        "the shared folder of earlier versions is no longer open",
        _mount("/var/lib/coral/bags", at="/bags"),
        OPEN_NETWORK,
        _outside("/var/lib/coral/bags"),
    ),
    (
        "data in the namespace's own folder",
        _mount("/var/lib/coral/data/robots/maps", at="/maps"),
        OPEN_NETWORK,
        [],
    ),
    (
        "the namespace's own folder itself, spelled differently",
        _mount("//var/lib/coral/./data/robots/", at="/data"),
        OPEN_NETWORK,
        [],
    ),
    (
        "the namespace's folder under a data root the administrator chose",
        _mount("/data/robots/maps", at="/maps"),
        {**OPEN_NETWORK, "CORAL_POLICY_DATA_ROOT": "/data"},
        [],
    ),
    (
        "another namespace's plugins, even in a folder opened by the administrator",
        _mount("/var/lib/coral/plugins/other", at="/p", readOnly=False),
        {**OPEN_NETWORK, "CORAL_POLICY_HOST_PATHS": "robots=/var/lib/coral"},
        [
            "spec.drivers[0] (lidar): hostPaths[0].hostPath: host path /var/lib/coral/plugins/other overlaps "
            "the plugin root, which holds other systems' plugins"
        ],
    ),
    (
        "a folder holding every namespace's plugins",
        _mount("//var/lib/./coral/", at="/p"),
        {**OPEN_NETWORK, "CORAL_POLICY_HOST_PATHS": "robots=/var/lib/coral"},
        [
            "spec.drivers[0] (lidar): hostPaths[0].hostPath: host path /var/lib/coral overlaps "
            "the plugin root, which holds other systems' plugins"
        ],
    ),
    (
        "a folder opened by the administrator for the namespace",
        _mount("/srv/maps", at="/maps"),
        {**OPEN_NETWORK, "CORAL_POLICY_HOST_PATHS": "lab=/srv/bags,robots=/srv"},
        [],
    ),
    (
        "a folder opened by the administrator for every namespace",
        _mount("/srv/maps/site", at="/maps"),
        {**OPEN_NETWORK, "CORAL_POLICY_HOST_PATHS": "*=/srv/maps"},
        [],
    ),
    (
        "a folder opened by the administrator for another namespace only",
        _mount("/srv/bags", at="/bags"),
        {**OPEN_NETWORK, "CORAL_POLICY_HOST_PATHS": "lab=/srv/bags"},
        _outside("/srv/bags"),
    ),
    ("an allowed device", _driver(devices=[{"hostPath": "/dev/ttyUSB0"}]), OPEN_NETWORK, []),
    (
        "/dev/mem",
        _driver(devices=[{"hostPath": "/dev/mem"}]),
        OPEN_NETWORK,
        [f"spec.drivers[0] (lidar): devices[0].hostPath /dev/mem is not an allowed device {DEVICES}"],
    ),
    (
        "a device pattern does not cross folders",
        _driver(devices=[{"hostPath": "/dev/video0/../mem"}]),
        OPEN_NETWORK,
        [f"spec.drivers[0] (lidar): devices[0].hostPath /dev/mem is not an allowed device {DEVICES}"],
    ),
    (
        "hostPathRoot /etc",
        _spec(plugins={"hostPathRoot": "/etc"}),
        OPEN_NETWORK,
        ["spec.plugins.hostPathRoot: /etc is not an allowed plugin root (/var/lib/coral/plugins)"],
    ),
    (
        "hostPathRoot inside another namespace's plugins",
        _spec(plugins={"hostPathRoot": "/var/lib/coral/plugins/victims"}),
        OPEN_NETWORK,
        [
            "spec.plugins.hostPathRoot: /var/lib/coral/plugins/victims is not an allowed plugin root "
            "(/var/lib/coral/plugins)"
        ],
    ),
    (
        "hostPathRoot spelled differently",
        _spec(plugins={"hostPathRoot": "/var/lib/coral/plugins/"}),
        OPEN_NETWORK,
        [],
    ),
    (
        "everything at once is reported at once",
        _driver(privileged=True, runAsRoot=True, devices=[{"hostPath": "/dev/sda"}]),
        {},
        [
            HOST_NET_DENIED,
            "spec.drivers[0] (lidar): privileged is not allowed in namespace robots",
            "spec.drivers[0] (lidar): runAsRoot is not allowed in namespace robots",
            f"spec.drivers[0] (lidar): devices[0].hostPath /dev/sda is not an allowed device {DEVICES}",
        ],
    ),
]


@pytest.mark.parametrize(("story", "change", "environment", "expected"), ROWS, ids=[row[0] for row in ROWS])
def test_the_policy_refuses_exactly_what_it_does_not_allow(
    story: str,
    change: Callable[[dict[str, Any]], None],
    environment: dict[str, str],
    expected: list[str],
) -> None:
    raw = copy.deepcopy(BASE_SPEC)
    change(raw)
    spec = CoralSystemSpec.model_validate(raw)
    assert policy.evaluate_policy("robots", spec, config.from_environment(environment).policy) == expected


def test_the_default_policy_is_the_restrictive_one() -> None:
    assert config.from_environment({}).policy == policy.Policy()
    default = policy.Policy()
    assert not default.privileged_namespaces and not default.root_namespaces
    assert not default.host_network_namespaces
