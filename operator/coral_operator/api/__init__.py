"""The coral.dev/v1alpha1 API: pydantic models of CoralSystem and CoralInstance (the contract, the
CRD schema and its documentation). Other packages import the models from here."""

from coral_operator.api.base import CamelModel
from coral_operator.api.common import Condition, ConfigMapKeyRef, LabelSelector, LabelSelectorRequirement
from coral_operator.api.components import Component, DeviceMount, EnvVar, HostPathMount, Readiness, Resources
from coral_operator.api.instance import (
    ComponentState,
    ConfigRef,
    CoralInstanceSpec,
    CoralInstanceStatus,
    InstanceTree,
    NoProgress,
    PluginState,
    RobotState,
    TreeFailure,
    TreeState,
)
from coral_operator.api.names import API_VERSION, GROUP, VERSION
from coral_operator.api.rollout import (
    CanaryStatus,
    RolledBack,
    RolloutCounts,
    RolloutFailure,
    RolloutStatus,
)
from coral_operator.api.system import (
    CanarySpec,
    CoralSystemSpec,
    CoralSystemStatus,
    PluginsSpec,
    RobotCounts,
    RolloutSpec,
    RosSpec,
    SourceSpec,
    StartupSpec,
    TreeCounts,
    TreeSpec,
)

__all__ = [
    "RolloutStatus",
    "RolloutFailure",
    "RolloutCounts",
    "RolledBack",
    "CanaryStatus",
    "API_VERSION",
    "GROUP",
    "VERSION",
    "CamelModel",
    "CanarySpec",
    "Component",
    "ComponentState",
    "Condition",
    "ConfigMapKeyRef",
    "ConfigRef",
    "CoralInstanceSpec",
    "CoralInstanceStatus",
    "CoralSystemSpec",
    "CoralSystemStatus",
    "DeviceMount",
    "EnvVar",
    "HostPathMount",
    "InstanceTree",
    "LabelSelector",
    "LabelSelectorRequirement",
    "NoProgress",
    "PluginState",
    "PluginsSpec",
    "Readiness",
    "Resources",
    "RobotCounts",
    "RobotState",
    "RolloutSpec",
    "RosSpec",
    "SourceSpec",
    "StartupSpec",
    "TreeCounts",
    "TreeFailure",
    "TreeSpec",
    "TreeState",
]
