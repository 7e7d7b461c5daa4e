"""The executors' identity is per system (three objects per system, not per robot), and the
admission policy that confines each executor to its own robot's instance is fail-closed."""

from __future__ import annotations

from coral_core.names import LABEL_SYSTEM
from coral_operator.planning import naming, rbac


def test_every_executor_of_a_system_shares_one_account_that_writes_only_status() -> None:
    objects = rbac.build_executor_rbac(system="mission", namespace="fleet", system_uid="uid-1")
    assert [o["kind"] for o in objects] == ["ServiceAccount", "Role", "RoleBinding"]
    assert {o["metadata"]["name"] for o in objects} == {naming.executor_account_name("mission")}
    role = objects[1]
    # Reading instances lets an executor follow its own `spec.halt`; it writes nothing but status.
    assert role["rules"] == [
        {"apiGroups": ["coral.dev"], "resources": ["coralinstances/status"], "verbs": ["patch"]},
        {"apiGroups": ["coral.dev"], "resources": ["coralinstances"], "verbs": ["get", "list", "watch"]},
    ]
    owner = objects[0]["metadata"]["ownerReferences"][0]
    assert (owner["kind"], owner["name"], owner["uid"]) == ("CoralSystem", "mission", "uid-1")


def test_two_systems_have_different_accounts_even_with_long_names() -> None:
    long_a, long_b = "a" * 200 + "-one", "a" * 200 + "-two"
    names = {naming.executor_account_name(s) for s in ("mission", "patrol", long_a, long_b)}
    assert len(names) == 4
    assert all(len(name) <= 253 and name.startswith(naming.EXECUTOR_ACCOUNT_PREFIX) for name in names)


def test_the_policy_refuses_on_error_and_checks_system_and_node() -> None:
    policy, binding = rbac.build_admission_policy()
    assert policy["spec"]["failurePolicy"] == "Fail"
    assert binding["spec"] == {"policyName": policy["metadata"]["name"], "validationActions": ["Deny"]}
    (rule,) = policy["spec"]["matchConstraints"]["resourceRules"]
    assert rule["resources"] == ["coralinstances/status"]
    checks = " ".join(v["expression"] for v in policy["spec"]["validations"])
    assert rbac.NODE_NAME_EXTRA in checks and "oldObject.spec.nodeName" in checks
    assert f"oldObject.metadata.labels['{LABEL_SYSTEM}']" in checks
    assert all(v["reason"] == "Forbidden" for v in policy["spec"]["validations"])
