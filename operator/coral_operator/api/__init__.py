"""The coral.dev/v1alpha1 API: pydantic models of CoralSystem and CoralInstance (the contract, the
CRD schema and its documentation). Other packages import the models from here.

The CoralInstance's status, the condition shape, the model base and the API's names belong to the
contract with the robot side and are defined in `coral_core`; they are re-exported here so the
operator's API is one surface.
"""

from coral_core.halt import HaltRequest
from coral_core.instance_status import (
    ComponentState,
    CoralInstanceStatus,
    NoProgress,
    PluginState,
    RobotState,
    TreeFailure,
    TreeHalt,
    TreeState,
)
from coral_core.names import API_VERSION, GROUP, VERSION
from coral_core.wire import CamelModel, Condition

from coral_operator.api.common import ConfigMapKeyRef, LabelSelector, LabelSelectorRequirement
from coral_operator.api.components import (
    Component,
    DeviceMount,
    EnvVar,
    ExecutorComponent,
    ExecutorMetricsSpec,
    Groot2Spec,
    HostPathMount,
    Readiness,
    Resources,
)
from coral_operator.api.instance import ConfigRef, CoralInstanceSpec, InstanceTree
from coral_operator.api.overrides import ComponentsAdded, Override, TreeOverride
from coral_operator.api.rollout import (
    CanaryStatus,
    PrePullStatus,
    PullFailure,
    RolledBack,
    RolloutCounts,
    RolloutFailure,
    RolloutStatus,
)
from coral_operator.api.system import (
    CanarySpec,
    CoralSystemSpec,
    CoralSystemStatus,
    HaltSpec,
    PluginsSpec,
    PrePullSpec,
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
    "PrePullStatus",
    "PullFailure",
    "PrePullSpec",
    "API_VERSION",
    "GROUP",
    "VERSION",
    "CamelModel",
    "CanarySpec",
    "Component",
    "ComponentsAdded",
    "ComponentState",
    "Condition",
    "ConfigMapKeyRef",
    "ConfigRef",
    "CoralInstanceSpec",
    "CoralInstanceStatus",
    "CoralSystemSpec",
    "CoralSystemStatus",
    "DeviceMount",
    "ExecutorComponent",
    "ExecutorMetricsSpec",
    "Groot2Spec",
    "EnvVar",
    "HaltRequest",
    "HaltSpec",
    "HostPathMount",
    "InstanceTree",
    "LabelSelector",
    "LabelSelectorRequirement",
    "NoProgress",
    "Override",
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
    "TreeOverride",
    "TreeHalt",
    "TreeSpec",
    "TreeState",
]
