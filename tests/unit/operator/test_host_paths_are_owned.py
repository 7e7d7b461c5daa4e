"""Host paths are owned per namespace, mounted so a planted link cannot lead out, and handed to the
components' user by an image the operator controls (issue 47, items 1 to 3).

Before: any namespace could mount any folder under `/var/lib/coral`, compared as a string and
mounted as a plain hostPath, which containerd follows through a link another pod planted there (the
robot's `/etc` was read, another namespace's plugin folder written); and the step that hands the
plugin folder to the components' user ran `chown` from the component's own image as root.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from coral_operator import config
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import CoralSystemSpec, StartupSpec
from coral_operator.kube import observing
from coral_operator.planning import instances, pods, policy
from coral_operator.status import instance_status
from operator_specs import BASE_SPEC, NOW, instance_view, robot

OPENED = policy.Policy(host_paths=(("robots", "/srv/maps"), ("*", "/srv/shared"), ("lab", "/srv/lab")))
HELPER = "registry.example/coral-operator:9"

# (story, namespace, requested path, (volume folder, subPath) or None when refused)
VOLUMES: list[tuple[str, str, str, tuple[str, str] | None]] = [
    (
        "the namespace's own folder",
        "robots",
        "/var/lib/coral/data/robots",
        ("/var/lib/coral/data/robots", ""),
    ),
    (
        "a folder inside its own, as the subPath",
        "robots",
        "/var/lib/coral/data/robots/maps/site",
        ("/var/lib/coral/data/robots", "maps/site"),
    ),
    ("another namespace's folder", "robots", "/var/lib/coral/data/lab/maps", None),
    ("climbing out of its own into another's", "robots", "/var/lib/coral/data/robots/../lab", None),
    ("the data root over every namespace", "robots", "/var/lib/coral/data", None),
    ("a look-alike name", "robots", "/var/lib/coral/data/robots2", None),
    ("the robot's /etc", "robots", "/etc", None),
    ("a folder the administrator opened for it", "robots", "/srv/maps/a", ("/srv/maps", "a")),
    ("a folder opened for every namespace", "lab", "/srv/shared", ("/srv/shared", "")),
    ("a folder opened for another namespace only", "robots", "/srv/lab", None),
]


@pytest.mark.parametrize(("story", "namespace", "path", "expected"), VOLUMES, ids=[row[0] for row in VOLUMES])
def test_a_host_path_is_mounted_from_the_allowed_folder_it_lies_in(
    story: str, namespace: str, path: str, expected: tuple[str, str] | None
) -> None:
    assert policy.host_path_volume(OPENED, namespace, path) == expected


def test_nested_folders_mount_from_the_innermost() -> None:
    nested = policy.Policy(host_paths=(("robots", "/var/lib/coral/data/robots/maps"),))
    placed = policy.host_path_volume(nested, "robots", "/var/lib/coral/data/robots/maps/a")
    assert placed == ("/var/lib/coral/data/robots/maps", "a")


# --- configuration ---------------------------------------------------------------------------

CONFIG_ERRORS: list[tuple[str, dict[str, str], str]] = [
    (
        "the retired prefix setting stops the operator",
        {"CORAL_POLICY_HOST_PATH_PREFIXES": "/var/lib/coral"},
        "CORAL_POLICY_HOST_PATH_PREFIXES is no longer read",
    ),
    (
        "a host path without its namespace",
        {"CORAL_POLICY_HOST_PATHS": "/srv/maps"},
        "CORAL_POLICY_HOST_PATHS",
    ),
    ("a relative folder", {"CORAL_POLICY_HOST_PATHS": "robots=srv"}, "CORAL_POLICY_HOST_PATHS"),
    ("a namespace that cannot exist", {"CORAL_POLICY_HOST_PATHS": "Robots=/srv"}, "CORAL_POLICY_HOST_PATHS"),
    (
        "a data root holding the plugin root",
        {"CORAL_POLICY_DATA_ROOT": "/var/lib/coral"},
        "overlaps the plugin root",
    ),
    ("a data root of /", {"CORAL_POLICY_DATA_ROOT": "/"}, "CORAL_POLICY_DATA_ROOT"),
]


@pytest.mark.parametrize(
    ("story", "environment", "named"), CONFIG_ERRORS, ids=[row[0] for row in CONFIG_ERRORS]
)
def test_a_setting_that_cannot_be_read_stops_the_operator_naming_it(
    story: str, environment: dict[str, str], named: str
) -> None:
    with pytest.raises(ValueError, match=named):
        config.from_environment(environment)


def test_the_settings_are_read_as_the_chart_writes_them() -> None:
    read = config.from_environment(
        {
            "CORAL_POLICY_DATA_ROOT": "/data/",
            "CORAL_POLICY_HOST_PATHS": "robots=/srv/maps/, *=/srv/shared,robots=/srv/maps",
            "CORAL_HELPER_IMAGE": HELPER,
        }
    )
    assert read.policy.data_root == "/data"
    assert read.policy.host_paths == (("*", "/srv/shared"), ("robots", "/srv/maps"))
    assert read.helper_image == HELPER
    # The chart writes every variable, empty ones included: empty means the default, not none.
    defaults = config.from_environment({"CORAL_POLICY_DATA_ROOT": "", "CORAL_HELPER_IMAGE": ""})
    assert defaults.policy.data_root == "/var/lib/coral/data"
    assert defaults.helper_image == pods.DEFAULT_HELPER_IMAGE


# --- pods ------------------------------------------------------------------------------------


def _built(spec: dict[str, Any], *, namespace: str = "robots") -> dict[str, dict[str, Any]]:
    template = instances.build_template(CoralSystemSpec.model_validate(spec), "t", "p")
    parsed = CoralInstanceSpec.model_validate(instances.build_instance_spec("sys", robot("r1"), template))
    built = pods.build_pods(
        spec=parsed,
        instance="sys-r1",
        namespace=namespace,
        instance_uid="u",
        settings=pods.PodSettings(policy=OPENED, helper_image=HELPER),
    )
    return {
        c["name"]: {"pod": p, "container": c}
        for p in built
        for c in [*p["spec"].get("initContainers", []), *p["spec"]["containers"]]
        if c["name"] != pods.FOLDERS_OWNER
    }


def _owner(pod: dict[str, Any]) -> dict[str, Any]:
    return next(c for c in pod["spec"]["initContainers"] if c["name"] == pods.FOLDERS_OWNER)


MAPS = [
    {"hostPath": "/var/lib/coral/data/robots/maps", "mountPath": "/maps", "readOnly": False},
    {"hostPath": "/srv/maps", "mountPath": "/site", "readOnly": True},
]


def test_a_host_path_mounts_its_folder_as_the_volume_and_the_rest_as_a_sub_path(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    slam = _built(spec_dict(skillsets=[{"name": "slam", "image": "example/slam:1", "hostPaths": MAPS}]))[
        "slam"
    ]
    volumes = {v["name"]: v for v in slam["pod"]["spec"]["volumes"]}
    mounts = {m["name"]: m for m in slam["container"]["volumeMounts"]}
    # The namespace's folder is the operator's: created where missing, never a tenant's link.
    assert volumes["host-0"]["hostPath"] == {
        "path": "/var/lib/coral/data/robots",
        "type": "DirectoryOrCreate",
    }
    assert mounts["host-0"] == {"name": "host-0", "mountPath": "/maps", "readOnly": False, "subPath": "maps"}
    assert volumes["host-1"]["hostPath"] == {"path": "/srv/maps"}
    assert mounts["host-1"] == {"name": "host-1", "mountPath": "/site", "readOnly": True}


def test_the_ownership_step_runs_the_helper_image_never_the_components(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    slam = _built(spec_dict(skillsets=[{"name": "slam", "image": "example/slam:1", "hostPaths": MAPS}]))[
        "slam"
    ]
    owner = _owner(slam["pod"])
    assert owner["image"] == HELPER
    assert "imagePullPolicy" not in owner
    # Each mount point alone, not recursively and not through a link: a link a tenant planted in
    # its folder is never followed by root.
    assert owner["command"] == [
        "chown",
        "--no-dereference",
        "10001:10001",
        "/coral-owned/plugins",
        "/coral-owned/host-0",
    ]
    owned = {m["mountPath"]: m for m in owner["volumeMounts"]}
    assert owned["/coral-owned/host-0"] == {
        "name": "host-0",
        "mountPath": "/coral-owned/host-0",
        "readOnly": False,
        "subPath": "maps",
    }
    # The administrator's folder stays as the administrator made it.
    assert all(m["name"] != "host-1" for m in owner["volumeMounts"])
    assert owner["securityContext"]["capabilities"] == {"drop": ["ALL"], "add": ["CHOWN"]}


def test_no_user_image_ever_runs_as_uid_0(spec_dict: Callable[..., dict[str, Any]]) -> None:
    spec = spec_dict(
        skillsets=[{"name": "slam", "image": "example/slam:1", "hostPaths": MAPS}],
        layout="PodPerComponent",
    )
    for layout in ("PodPerComponent", "PodPerRobot"):
        for entry in _built({**spec, "layout": layout}).values():
            container, pod = entry["container"], entry["pod"]
            assert container["securityContext"].get("runAsUser") != 0
            assert container["securityContext"].get("runAsNonRoot") is True
            for init in pod["spec"].get("initContainers", []):
                if init["securityContext"].get("runAsUser") == 0:
                    assert init["image"] == HELPER, init


def test_a_robot_pod_hands_over_its_data_folders_before_the_first_sidecar(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    spec = spec_dict(
        skillsets=[{"name": "slam", "image": "example/slam:1", "hostPaths": MAPS}], layout="PodPerRobot"
    )
    pod = _built(spec)["slam"]["pod"]
    first, *sidecars = pod["spec"]["initContainers"]
    assert first["name"] == pods.FOLDERS_OWNER and "restartPolicy" not in first
    assert first["command"][3:] == ["/coral-owned/c1-host-0"]
    assert [s["name"] for s in sidecars] == ["lidar", "slam"]


def test_a_robot_pod_without_data_folders_has_no_ownership_step(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    pod = _built(spec_dict(layout="PodPerRobot"))["slam"]["pod"]
    assert all(c["name"] != pods.FOLDERS_OWNER for c in pod["spec"]["initContainers"])


def test_an_instance_written_by_hand_with_a_path_outside_is_refused_by_the_builder(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    spec = spec_dict(
        drivers=[{"name": "lidar", "image": "l:1", "hostPaths": [{"hostPath": "/etc", "mountPath": "/x"}]}]
    )
    with pytest.raises(pods.HostPathRefused, match=r"hostPaths\[0\].hostPath of lidar: /etc is outside"):
        _built(spec)


# --- what the kubelet says reaches the instance ------------------------------------------------

SUBPATH_REFUSED = 'failed to prepare subPath for volumeMount "host-0" of container "folders-owner"'


def _view_with(body_status: dict[str, Any], layout: str = "PodPerComponent") -> Any:
    spec = {**BASE_SPEC, "layout": layout}
    template = instances.build_template(CoralSystemSpec.model_validate(spec), "t", "p")
    parsed = CoralInstanceSpec.model_validate(instances.build_instance_spec("sys", robot("r1"), template))
    desired = pods.build_pods(spec=parsed, instance="sys-r1", namespace="ns", instance_uid="u")
    observed = list(observing.observed_pods({"metadata": desired[0]["metadata"], "status": body_status}))
    return instance_view(parsed, desired, observed, startup=StartupSpec())


def _conditions(view: Any) -> dict[str, dict[str, Any]]:
    status = instance_status.build_instance_status(view, old_conditions=[], generation=1, now=NOW)
    return {c["type"]: c for c in status["conditions"]}


def _waiting(name: str, reason: str, message: str = "") -> dict[str, Any]:
    return {"name": name, "restartCount": 0, "state": {"waiting": {"reason": reason, "message": message}}}


def test_a_refused_ownership_step_stalls_the_instance_with_the_kubelets_message() -> None:
    conditions = _conditions(
        _view_with(
            {
                "phase": "Pending",
                "initContainerStatuses": [
                    _waiting("folders-owner", "CreateContainerConfigError", SUBPATH_REFUSED)
                ],
                "containerStatuses": [_waiting("lidar", "PodInitializing")],
            }
        )
    )
    assert conditions["ComponentsReady"]["reason"] == "ContainerRefused"
    assert conditions["Stalled"]["status"] == "True"
    assert f"lidar: CreateContainerConfigError: {SUBPATH_REFUSED}" in conditions["Stalled"]["message"]


def test_a_refused_ownership_step_of_a_robot_pod_holds_every_component() -> None:
    conditions = _conditions(
        _view_with(
            {
                "phase": "Pending",
                "initContainerStatuses": [
                    _waiting("folders-owner", "CreateContainerConfigError", SUBPATH_REFUSED),
                    _waiting("lidar", "PodInitializing"),
                    _waiting("slam", "PodInitializing"),
                ],
                "containerStatuses": [_waiting("executor", "PodInitializing")],
            },
            layout="PodPerRobot",
        )
    )
    assert conditions["ComponentsReady"]["reason"] == "ContainerRefused"
    assert SUBPATH_REFUSED in conditions["Ready"]["message"]


def test_a_new_helper_image_restarts_no_component(spec_dict: Callable[..., dict[str, Any]]) -> None:
    spec = spec_dict(skillsets=[{"name": "slam", "image": "example/slam:1", "hostPaths": MAPS}])
    template = instances.build_template(CoralSystemSpec.model_validate(spec), "t", "p")
    parsed = CoralInstanceSpec.model_validate(instances.build_instance_spec("sys", robot("r1"), template))

    def names_with(image: str) -> list[str]:
        settings = pods.PodSettings(policy=OPENED, helper_image=image)
        built = pods.build_pods(
            spec=parsed, instance="i", namespace="robots", instance_uid="u", settings=settings
        )
        return [p["metadata"]["name"] for p in built]

    assert names_with("helper:1") == names_with("helper:2")
