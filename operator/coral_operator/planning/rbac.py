"""The executors' identity: one ServiceAccount and Role per system, confined per robot by admission.

An executor may patch the status of its own robot's CoralInstance and nothing else (no other
instance, no spec, no pods, no secrets, no CoralSystems). RBAC alone could scope that only with
one Role per instance (`resourceNames`), three objects per robot. Instead:

- each system has one ServiceAccount, Role and RoleBinding, owned by the CoralSystem; the Role
  allows `patch` on `coralinstances/status` and reading `coralinstances` (an executor follows its
  instance's `spec.halt`) in the namespace, and nothing else;
- one cluster-wide ValidatingAdmissionPolicy (with its binding) narrows that to one instance: the
  request must come from the account of the instance's system (its `coral.dev/system` label) and
  from a token bound to a pod on the instance's Node. The kubelet's projected token carries that
  Node's name in the user's extra field `authentication.kubernetes.io/node-name`, which only the
  API server sets.

Pure; the system's objects are applied by the system handler. The policy is rendered into the Helm
chart by `make crds` (a namespaced install grants no cluster-wide writes) and checked at operator
start-up: applied when its `coral.dev/policy-hash` annotation differs from this module's.
"""

from __future__ import annotations

from typing import Any

import yaml
from coral_core import names
from coral_core.names import API_VERSION, GROUP

from coral_operator.planning import naming

POLICY_NAME = f"coral-executor-own-instance.{names.GROUP}"
POLICY_HASH_ANNOTATION = f"{names.GROUP}/policy-hash"
NODE_NAME_EXTRA = "authentication.kubernetes.io/node-name"
_ADMISSION = "admissionregistration.k8s.io/v1"
# CEL over the admission request. `oldObject` is the instance before the patch: the executor's
# write cannot move the instance to another robot or system to pass the check.
_IS_EXECUTOR = (
    f"request.userInfo.username.matches('^system:serviceaccount:[^:]+:{naming.EXECUTOR_ACCOUNT_PREFIX}')"
)
_SAME_SYSTEM = (
    f"has(oldObject.metadata.labels) && '{names.LABEL_SYSTEM}' in oldObject.metadata.labels && "
    f"request.userInfo.username == 'system:serviceaccount:' + request.namespace + "
    f"':{naming.EXECUTOR_ACCOUNT_PREFIX}' + oldObject.metadata.labels['{names.LABEL_SYSTEM}']"
)
_SAME_NODE = (
    f"has(request.userInfo.extra) && '{NODE_NAME_EXTRA}' in request.userInfo.extra && "
    f"request.userInfo.extra['{NODE_NAME_EXTRA}'] == [oldObject.spec.nodeName]"
)


def build_executor_rbac(*, system: str, namespace: str, system_uid: str) -> list[dict[str, Any]]:
    """ServiceAccount, Role and RoleBinding of the executors of one system."""
    name = naming.executor_account_name(system)
    metadata = {
        "name": name,
        "namespace": namespace,
        "labels": {names.LABEL_SYSTEM: naming.label_value(system), names.LABEL_MANAGED_BY: names.MANAGER},
        "ownerReferences": [naming.owner_reference(API_VERSION, names.SYSTEM_KIND, system, system_uid)],
    }
    return [
        {"apiVersion": "v1", "kind": "ServiceAccount", "metadata": dict(metadata)},
        {
            "apiVersion": "rbac.authorization.k8s.io/v1",
            "kind": "Role",
            "metadata": dict(metadata),
            "rules": [
                {"apiGroups": [GROUP], "resources": ["coralinstances/status"], "verbs": ["patch"]},
                # The executor follows its instance's `spec.halt` (`coral.executor.halt_watch`).
                {"apiGroups": [GROUP], "resources": ["coralinstances"], "verbs": ["get", "list", "watch"]},
            ],
        },
        {
            "apiVersion": "rbac.authorization.k8s.io/v1",
            "kind": "RoleBinding",
            "metadata": dict(metadata),
            "roleRef": {"apiGroup": "rbac.authorization.k8s.io", "kind": "Role", "name": name},
            "subjects": [{"kind": "ServiceAccount", "name": name, "namespace": namespace}],
        },
    ]


def build_admission_policy() -> list[dict[str, Any]]:
    """The cluster-wide ValidatingAdmissionPolicy and its binding that confine every executor."""
    labels = {names.LABEL_MANAGED_BY: names.MANAGER}
    policy = {
        "apiVersion": _ADMISSION,
        "kind": "ValidatingAdmissionPolicy",
        "metadata": {"name": POLICY_NAME, "labels": labels},
        "spec": {
            # An error in evaluating the policy refuses the write: never open by accident.
            "failurePolicy": "Fail",
            "matchConstraints": {
                "resourceRules": [
                    {
                        "apiGroups": [GROUP],
                        "apiVersions": ["*"],
                        "operations": ["UPDATE"],
                        "resources": ["coralinstances/status"],
                    }
                ]
            },
            "matchConditions": [{"name": "coral-executor", "expression": _IS_EXECUTOR}],
            "validations": [
                {
                    "expression": _SAME_SYSTEM,
                    "reason": "Forbidden",
                    "message": "a Coral executor may patch only the CoralInstances of its own system",
                },
                {
                    "expression": _SAME_NODE,
                    "reason": "Forbidden",
                    "message": "a Coral executor may patch only the CoralInstance of its pod's Node",
                },
            ],
        },
    }
    binding = {
        "apiVersion": _ADMISSION,
        "kind": "ValidatingAdmissionPolicyBinding",
        "metadata": {"name": POLICY_NAME, "labels": labels},
        "spec": {"policyName": POLICY_NAME, "validationActions": ["Deny"]},
    }
    for manifest in (policy, binding):
        manifest["metadata"]["annotations"] = {POLICY_HASH_ANNOTATION: naming.content_hash(manifest)}
    return [policy, binding]


def render_admission_policy() -> str:
    """The policy and its binding as the chart's template.

    Both are cluster-scoped, one per cluster, while the chart may be installed once per namespace
    (and the operator applies them itself when it may). So each is rendered only when the cluster
    has none yet or this release made it: a second release, or a policy the operator applied,
    is left as it is instead of failing the install. `helm template` (no cluster) renders both.
    """
    header = "# Generated from coral_operator/planning/rbac.py by hack/generate-crds.py; do not edit.\n"
    documents = []
    for manifest in build_admission_policy():
        guard = (
            f'{{{{- $found := lookup "{manifest["apiVersion"]}" "{manifest["kind"]}" "" '
            f'"{manifest["metadata"]["name"]}" }}}}\n'
            '{{- $owner := dig "metadata" "annotations" "meta.helm.sh/release-name" "" $found }}\n'
            '{{- $home := dig "metadata" "annotations" "meta.helm.sh/release-namespace" "" $found }}\n'
            "{{- if or (not $found) (and (eq $owner .Release.Name) (eq $home .Release.Namespace)) }}\n"
        )
        body = yaml.safe_dump(manifest, sort_keys=True, width=100)
        documents.append(guard + "---\n" + body + "{{- end }}\n")
    return header + "".join(documents)
