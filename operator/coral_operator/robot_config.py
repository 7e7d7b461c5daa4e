"""What one robot of a CoralSystem runs, as `coral config SYSTEM ROBOT` shows it (also used by tests).

`explain` is pure: from the system, the robot's Node, the system's files and the robot's
CoralInstance, the robot's effective configuration resolved as the operator resolves it
(`planning.effective`, the same hash), validated, and whether the robot runs it yet.
`ConfigReader` reads those inputs with the user's own identity.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from coral_core import names
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException
from pydantic import ValidationError

from coral_operator import user_client
from coral_operator.api.common import ConfigMapKeyRef
from coral_operator.api.system import CoralSystemSpec
from coral_operator.kube import observing
from coral_operator.planning import configmaps, effective, instances, naming, validation
from coral_operator.planning.observed import RobotNode
from coral_operator.planning.overrides import BaseConfig, ConfigError, EffectiveConfig, effective_config


class ConfigReadError(Exception):
    """The inputs cannot be read; the message says which and why."""


@dataclass(frozen=True)
class Component:
    kind: str
    name: str
    image: str
    env: dict[str, str]


@dataclass
class RobotConfig:
    """One robot's effective configuration and where it stands."""

    system: str
    robot: str
    overrides: tuple[str, ...] = ()
    """The overrides that match the robot, in spec order."""
    config_hash: str | None = None
    """What the operator writes as the instance's `spec.configHash` for the spec's revision."""
    running_hash: str | None = None
    """The instance's `spec.configHash` now (None: no instance yet)."""
    running_revision: str | None = None
    main_tree_id: str | None = None
    tree: str = ""
    tree_files: dict[str, str] = field(default_factory=dict)
    parameters: str = ""
    components: list[Component] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    """Why the robot has no valid configuration, each naming the field or file and line."""

    @property
    def valid(self) -> bool:
        return not self.problems

    @property
    def runs_it(self) -> bool:
        return self.config_hash is not None and self.running_hash == self.config_hash

    def to_json(self) -> dict[str, Any]:
        return {
            "system": self.system,
            "robot": self.robot,
            "valid": self.valid,
            "problems": self.problems,
            "overrides": list(self.overrides),
            "configHash": self.config_hash,
            "running": {"configHash": self.running_hash, "revision": self.running_revision},
            "tree": {"mainTreeId": self.main_tree_id, "tree.xml": self.tree, "files": self.tree_files},
            "parameters": self.parameters,
            "components": [
                {"kind": c.kind, "name": c.name, "image": c.image, "env": c.env} for c in self.components
            ],
        }


def explain(
    *,
    system: Mapping[str, Any],
    node: RobotNode,
    tree: str,
    parameters: str,
    instance: Mapping[str, Any] | None = None,
) -> RobotConfig:
    """The robot's effective configuration at the spec's revision, validated as the operator does."""
    metadata = system.get("metadata") or {}
    name, namespace, uid = metadata.get("name", ""), metadata.get("namespace", ""), metadata.get("uid", "")
    said = RobotConfig(system=name, robot=node.robot)
    spec_of_instance = (instance or {}).get("spec") or {}
    said.running_hash = spec_of_instance.get(effective.CONFIG_HASH)
    said.running_revision = spec_of_instance.get("revision")
    try:
        spec = CoralSystemSpec.model_validate(system.get("spec") or {})
    except ValidationError as error:
        said.problems = [f"spec.{'.'.join(str(p) for p in e['loc'])}: {e['msg']}" for e in error.errors()]
        return said
    tree_label, params_label = f"coralsystem/{name} spec.tree", f"coralsystem/{name} spec.parameters"
    said.problems = validation.validate_tree(
        tree, tree_label, spec.tree.main_tree_id, spec.tree.files, files_label=f"{tree_label}.files"
    ) + validation.validate_parameters(parameters, params_label)
    config = effective_config(BaseConfig.of_spec(spec, tree, parameters), spec.overrides, node)
    if isinstance(config, ConfigError):
        said.problems.append(str(config))
        return said
    _describe(said, config)
    if said.problems:
        return said
    common = {"system": name, "namespace": namespace, "system_uid": uid}
    tree_cm = configmaps.build_config_map(
        **common, kind="tree", key=configmaps.TREE_KEY, text=tree, beside=spec.tree.files
    )
    params_cm = configmaps.build_config_map(
        **common, kind="params", key=configmaps.PARAMS_KEY, text=parameters
    )
    template = effective.with_overrides(
        instances.build_template(spec, tree_cm["metadata"]["name"], params_cm["metadata"]["name"]),
        spec,
        tree,
        parameters,
    )
    resolved = effective.EffectiveTemplates(**common).resolve(template, node)
    if isinstance(resolved, ConfigError):
        said.problems.append(str(resolved))
    else:
        said.config_hash = resolved[effective.CONFIG_HASH]
    return said


def _describe(said: RobotConfig, config: EffectiveConfig) -> None:
    said.overrides = config.applied
    said.main_tree_id = config.main_tree_id
    said.tree, said.tree_files, said.parameters = config.tree, dict(config.tree_files), config.parameters
    said.components = [
        Component(kind, c.name, c.image, {e.name: e.value for e in c.env})
        for kind in ("drivers", "skillsets", "executors")
        for c in getattr(config, kind)
    ]


class ConfigReader:
    """Reads what `explain` needs from the cluster, with the user's identity."""

    def __init__(self, api_client: k8s.ApiClient, namespace: str) -> None:
        self.api_client = api_client
        self.custom = k8s.CustomObjectsApi(api_client)
        self.core = k8s.CoreV1Api(api_client)
        self.namespace = namespace

    @classmethod
    def from_kubeconfig(cls, namespace: str) -> ConfigReader:
        return cls(user_client.user_api_client(), namespace)

    def read(self, system: str, robot: str) -> RobotConfig:
        try:
            body = self.custom.get_namespaced_custom_object(
                names.GROUP, names.VERSION, self.namespace, names.SYSTEM_PLURAL, system
            )
        except ApiException as error:
            if error.status == 404:
                raise ConfigReadError(
                    f"coralsystem/{system} not found in namespace {self.namespace}"
                ) from error
            raise
        nodes = self.core.list_node(label_selector=f"{names.LABEL_ROBOT}={robot}").items
        if not nodes:
            raise ConfigReadError(f"no Node is labelled {names.LABEL_ROBOT}={robot}")
        node = nodes[0]
        record = observing.robot_node(
            node.metadata.name,
            node.metadata.labels or {},
            self.api_client.sanitize_for_serialization(node.status) or {},
            None,
            node.metadata.annotations or {},
        )
        assert record is not None  # selected by its robot label
        spec = body.get("spec") or {}
        return explain(
            system=body,
            node=record,
            tree=self._source(spec.get("tree") or {}, "tree"),
            parameters=self._source(spec.get("parameters") or {}, "parameters"),
            instance=self._instance(system, robot),
        )

    def _source(self, source: Mapping[str, Any], field: str) -> str:
        if source.get("inline") is not None:
            return str(source["inline"])
        ref = ConfigMapKeyRef.model_validate(source.get("configMapRef") or {})
        try:
            found = self.core.read_namespaced_config_map(ref.name, self.namespace)
        except ApiException as error:
            raise ConfigReadError(
                f"spec.{field}.configMapRef: ConfigMap {ref.name} cannot be read"
            ) from error
        # What the operator refuses to read, it deploys nothing from: say so rather than show it.
        refused = configmaps.source_refusal(
            f"spec.{field}.configMapRef", ref.name, (found.metadata.labels or {}) if found.metadata else {}
        )
        if refused is not None:
            raise ConfigReadError(refused)
        text = (found.data or {}).get(ref.key)
        if text is None:
            raise ConfigReadError(f"spec.{field}.configMapRef: ConfigMap {ref.name} has no key {ref.key}")
        return str(text)

    def _instance(self, system: str, robot: str) -> dict[str, Any] | None:
        try:
            return self.custom.get_namespaced_custom_object(
                names.GROUP,
                names.VERSION,
                self.namespace,
                names.INSTANCE_PLURAL,
                naming.instance_name(system, robot),
            )
        except ApiException as error:
            if error.status == 404:
                return None
            raise
