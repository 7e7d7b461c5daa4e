"""The names of the coral.dev API: group, version, kinds, labels and annotations (DESIGN section 3).

Defined here once; the operator's builders and handlers, `coral rollout`, the CRD generator and
the executor's status sink all import them from here. The wire names of status fields are not
here: `coral_core.keys` and `coral_operator.api.keys` derive them from the models.
"""

from __future__ import annotations

GROUP = "coral.dev"
VERSION = "v1alpha1"
API_VERSION = f"{GROUP}/{VERSION}"

COORDINATION_BEHAVIORS = ("TriggerRemote", "WaitForRemoteTrigger", "ShareValue", "WaitForSharedValue")
"""Behaviors every executor provides itself (`coral.coordination`): no image exports them."""

SYSTEM_KIND = "CoralSystem"
SYSTEM_PLURAL = "coralsystems"
INSTANCE_KIND = "CoralInstance"
INSTANCE_PLURAL = "coralinstances"

LABEL_ROBOT = f"{GROUP}/robot"
"""On a Node: the robot's name; the Node is a robot. On what the operator creates: its robot."""
LABEL_SYSTEM = f"{GROUP}/system"
LABEL_INSTANCE = f"{GROUP}/instance"
LABEL_COMPONENT = f"{GROUP}/component"
LABEL_ROLE = f"{GROUP}/role"
LABEL_REVISION = f"{GROUP}/revision"
LABEL_LAYOUT = f"{GROUP}/layout"
LABEL_MANAGED_BY = "app.kubernetes.io/managed-by"
LABEL_SOURCE = f"{GROUP}/source"
"""On a ConfigMap, set to "true" by whoever may write it: CoralSystems of its namespace may name it
in `configMapRef` (the operator reads no other ConfigMap for them; issue 47, item 9)."""
MANAGER = "coral-operator"
"""`LABEL_MANAGED_BY` of everything the operator creates, and its field manager and user agent."""
EXECUTOR_MANAGER = "coral-executor"
"""The field manager and user agent of an executor's status writes to its CoralInstance."""

ANNOTATION_POD_HASH = f"{GROUP}/pod-hash"
"""On a pod: the hash of the spec it was built from."""
ANNOTATION_COMPONENTS = f"{GROUP}/components"
"""On a robot pod (`PodPerRobot`): its containers as `role:name` in startup order."""
ANNOTATION_SHAPE_HASH = f"{GROUP}/shape-hash"
"""On a robot pod: the hash of its spec without images (equal shapes differ in images only, which a
pod can change in place)."""
ANNOTATION_ROLLOUT_UNDO = f"{GROUP}/rollout-undo"
"""On a CoralSystem, set by `coral rollout undo`: the revision to roll back from."""
ANNOTATION_ROLLOUT_RESUME = f"{GROUP}/rollout-resume"
"""On a CoralSystem, set by `coral rollout resume`: the time of the recorded failure it clears."""
ANNOTATION_OBSERVED = f"{GROUP}/observed"
"""On a CoralSystem: a digest of what changed around it, written to wake its handler."""
