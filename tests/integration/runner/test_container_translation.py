"""Pure rules that turn a container spec into a local process (no cluster needed; fast)."""

from __future__ import annotations

from pathlib import Path

import pytest
from coral_testbed.runner import podspec, podstatus

POD = {
    "metadata": {"name": "p", "namespace": "ns", "uid": "u1", "labels": {"app": "x"}},
    "spec": {"nodeName": "r1", "serviceAccountName": "sa"},
}


def lookup(kind: str, namespace: str, name: str) -> dict[str, str] | None:
    objects = {("ConfigMap", "ns", "cm"): {"a": "1", "b": "2"}, ("Secret", "ns", "s"): {"pw": "hunter2"}}
    return objects.get((kind, namespace, name))


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("/coral/config/tree.xml", "/local/config/tree.xml"),
        ("--tree=/coral/config/tree.xml", "--tree=/local/config/tree.xml"),
        ("open('/coral/plugins/x')", "open('/local/plugins/x')"),
        ("/coral/plugins", "/local/plugins"),
        ("/coral/pluginsextra", "/coral/pluginsextra"),
        ("/other/coral/plugins", "/other/coral/plugins"),
        ("a:/coral/config:b", "a:/local/config:b"),
    ],
    ids=[
        "rewrite a path below a mount",
        "rewrite after an equals sign",
        "rewrite inside quoted code",
        "rewrite the mount itself",
        "leave a longer name alone",
        "leave a path that only contains the mount alone",
        "rewrite inside a colon list",
    ],
)
def test_mount_paths_are_rewritten_only_where_a_path_starts(text: str, expected: str) -> None:
    paths = podspec.PathMap.of(
        {"/coral/config": Path("/local/config"), "/coral/plugins": Path("/local/plugins")}
    )
    assert paths.rewrite(text) == expected


def test_env_follows_kubernetes_order_and_expansion() -> None:
    container = {
        "name": "c",
        "envFrom": [{"configMapRef": {"name": "cm"}, "prefix": "P_"}, {"secretRef": {"name": "s"}}],
        "env": [
            {"name": "P_a", "value": "override"},
            {"name": "NODE", "valueFrom": {"fieldRef": {"fieldPath": "spec.nodeName"}}},
            {"name": "APP", "valueFrom": {"fieldRef": {"fieldPath": "metadata.labels['app']"}}},
            {"name": "MSG", "value": "on $(NODE) $(UNKNOWN) $$(NODE)"},
            {"name": "OPT", "valueFrom": {"configMapKeyRef": {"name": "nope", "key": "k", "optional": True}}},
        ],
    }
    env = podspec.container_env(POD, container, lookup, host_ip="10.0.0.2")
    assert env == {
        "P_a": "override",
        "P_b": "2",
        "pw": "hunter2",
        "NODE": "r1",
        "APP": "x",
        "MSG": "on r1 $(UNKNOWN) $(NODE)",
    }


def test_missing_configmap_key_names_the_container_and_variable() -> None:
    container = {
        "name": "c",
        "env": [{"name": "X", "valueFrom": {"configMapKeyRef": {"name": "cm", "key": "z"}}}],
    }
    with pytest.raises(podspec.ContainerConfigError, match=r"containers\[c\]\.env\[X\].*no key 'z'"):
        podspec.container_env(POD, container, lookup, host_ip="10.0.0.2")


def test_image_without_command_uses_its_mapped_entrypoint_or_fails_clearly() -> None:
    paths = podspec.PathMap.of({})
    container = {"name": "c", "image": "ghcr.io/x/skillset:1.2", "args": ["--name", "$(N)"]}
    entrypoints = {"ghcr.io/x/skillset": ["python", "-m", "skills"]}
    argv = podspec.container_argv(container, {"N": "s1"}, paths, entrypoints)
    assert argv == ["python", "-m", "skills", "--name", "s1"]
    with pytest.raises(podspec.ContainerConfigError, match="no local entrypoint"):
        podspec.container_argv(container, {}, paths, {})


@pytest.mark.parametrize(
    ("states", "phase"),
    [
        ([{"terminated": {"exitCode": 0}}], "Succeeded"),
        ([{"terminated": {"exitCode": 0}}, {"terminated": {"exitCode": 2}}], "Failed"),
        ([{"running": {}}, {"terminated": {"exitCode": 2}}], "Running"),
        ([{"waiting": {"reason": "CrashLoopBackOff"}}], "Running"),
        ([{"waiting": {"reason": "ContainerCreating"}}], "Pending"),
    ],
    ids=["all exited zero", "one failed", "one still running", "restarting", "not started yet"],
)
def test_pod_phase_follows_container_states(states: list[dict], phase: str) -> None:
    assert podstatus.evaluate_phase(states, prepared=True) == phase


def test_signal_exit_codes_follow_the_128_plus_signal_convention() -> None:
    assert podstatus.exit_code_of(-15) == 143
    assert podstatus.exit_code_of(3) == 3
