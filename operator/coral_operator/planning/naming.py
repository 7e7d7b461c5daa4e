"""Names, label sets and content hashes of everything the operator creates.

One module so the handlers, the planners and the tests agree on every name; the API's own names
(group, labels, annotations) are `coral_core.names`. Pure.
"""

from __future__ import annotations

import hashlib
import json
import re
from typing import Any

from coral_core import names
from coral_core.instance_status import Role

ROBOT_POD = "robot"

_MAX_LABEL = 63
_MAX_SUBDOMAIN = 253
_POD_SUFFIX_LENGTH = 5
_SUFFIX_ALPHABET = "bcdfghjklmnpqrstvwxz2456789"


def content_hash(value: Any, length: int = 10) -> str:
    """A short, stable hash of any JSON-ready value."""
    text = json.dumps(value, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:length]


HASH_LENGTH = 16
"""Hex digits of the hash that ends every shortened or rewritten name: 64 bits, so that no tenant
can search for a name of theirs that shortens like another's (8 digits took minutes of CPU)."""

_HASHED = re.compile(rf"-[0-9a-f]{{{HASH_LENGTH}}}$")


def _verbatim(text: str, valid: bool, max_length: int) -> bool:
    """Whether `text` may stand for itself: valid, short enough, and not in the shape of a shortened
    name. Every shortened name ends in `-<HASH_LENGTH hex>` and no verbatim one does, so a name
    chosen to look like another's shortened form is shortened itself (issue 47, item 9)."""
    return valid and len(text) <= max_length and not _HASHED.search(text)


def _shortened(readable: str, whole: Any, max_length: int, strip: str = "-") -> str:
    """A prefix of `readable`, then `-` and a hash of `whole` (the entire input, not the prefix)."""
    prefix = readable[: max_length - HASH_LENGTH - 1].rstrip(strip) or "x"
    return f"{prefix}-{content_hash(whole, HASH_LENGTH)}"


def dns_label(text: str, max_length: int = _MAX_LABEL) -> str:
    """`text` as a DNS-1123 label, injective: kept when it is one already (and does not end like a
    shortened name), else a cleaned prefix and a hash of the whole of `text`."""
    cleaned = re.sub(r"[^a-z0-9-]+", "-", text.lower()).strip("-") or "x"
    if _verbatim(text, cleaned == text, max_length):
        return cleaned
    return _shortened(cleaned, text, max_length)


def label_value(text: str) -> str:
    """`text` usable as a label value (at most 63 characters), injective like `dns_label`."""
    if _verbatim(text, True, _MAX_LABEL):
        return text
    return _shortened(text, text, _MAX_LABEL, "-._")


def instance_name(system: str, robot: str) -> str:
    """CoralInstance of `robot` for `system`; short enough to be a label value.

    `<system>-<robot>` when that reads back uniquely: the system's name has no `-` (so the first
    `-` splits it), and the whole is a valid label not shaped like a shortened name. Otherwise a
    prefix and a hash of the pair: joined by `-` alone, "a-b" + "c" and "a" + "b-c" were one
    instance, and the second system was never served (issue 47, item 9).
    """
    joined = f"{system}-{robot}"
    readable = re.fullmatch(r"[a-z0-9]([a-z0-9-]*[a-z0-9])?", joined) is not None
    if "-" not in system and _verbatim(joined, readable, _MAX_LABEL):
        return joined
    cleaned = re.sub(r"[^a-z0-9-]+", "-", joined.lower()).strip("-") or "x"
    return _shortened(cleaned, [system, robot], _MAX_LABEL)


def pod_name(instance: str, component: str, pod_hash: str) -> str:
    """Pod of one component on one robot, named after its content like a ReplicaSet's pods.

    A name that changes with the content means a delete sent for a replaced pod can never hit its
    replacement, even when it is acted on late (kwok, for one, can act on it after the replacement
    exists). A restarted operator finds its pods by their labels and `names.ANNOTATION_POD_HASH`
    (`planning.startup`), not by name, so the name only has to be unique and valid.
    """
    suffix = _name_suffix(pod_hash)
    prefix = dns_label(f"{instance}-{component}", _MAX_SUBDOMAIN - len(suffix) - 1)
    return f"{prefix}-{suffix}"


def _name_suffix(pod_hash: str) -> str:
    # Spread the whole hash over the alphabet ReplicaSets use for their pod suffixes: no vowels and
    # no look-alike digits, so a suffix never spells a word and reads back unambiguously.
    number = int(hashlib.sha256(pod_hash.encode()).hexdigest(), 16)
    digits: list[str] = []
    for _ in range(_POD_SUFFIX_LENGTH):
        number, digit = divmod(number, len(_SUFFIX_ALPHABET))
        digits.append(_SUFFIX_ALPHABET[digit])
    return "".join(digits)


EXECUTOR_ACCOUNT_PREFIX = "coral-executor-"


def executor_account_name(system: str) -> str:
    """ServiceAccount (and Role, RoleBinding) of every executor of one system.

    The prefix followed by the system's label value: the admission policy (`planning.rbac`) tells an
    executor by the prefix and its system by the rest, which must equal the instance's system label.
    """
    return EXECUTOR_ACCOUNT_PREFIX + label_value(system)


def config_map_name(system: str, kind: str, digest: str) -> str:
    """Immutable ConfigMap holding one validated file (`tree` or `params`), named by content."""
    return f"{dns_label(system, 200)}-{kind}-{digest}"


def instance_labels(system: str, robot: str) -> dict[str, str]:
    """Labels of a CoralInstance (curated, never copied from the parent)."""
    return {
        names.LABEL_SYSTEM: label_value(system),
        names.LABEL_ROBOT: label_value(robot),
        names.LABEL_MANAGED_BY: names.MANAGER,
    }


def pod_labels(
    system: str, robot: str, instance: str, component: str, role: Role, revision: str
) -> dict[str, str]:
    """Labels of a component pod."""
    return {
        names.LABEL_SYSTEM: label_value(system),
        names.LABEL_ROBOT: label_value(robot),
        names.LABEL_INSTANCE: instance,
        names.LABEL_COMPONENT: component,
        names.LABEL_ROLE: role,
        names.LABEL_REVISION: revision,
        names.LABEL_MANAGED_BY: names.MANAGER,
    }


def robot_pod_labels(system: str, robot: str, instance: str, revision: str) -> dict[str, str]:
    """Labels of a robot pod: one robot's components in one pod, so no component or role label."""
    return {
        names.LABEL_SYSTEM: label_value(system),
        names.LABEL_ROBOT: label_value(robot),
        names.LABEL_INSTANCE: instance,
        names.LABEL_LAYOUT: "PodPerRobot",
        names.LABEL_REVISION: revision,
        names.LABEL_MANAGED_BY: names.MANAGER,
    }


def is_robot_pod(manifest: dict[str, Any]) -> bool:
    """The manifest is a robot pod (`PodPerRobot`), not one component's."""
    return names.ANNOTATION_COMPONENTS in (manifest["metadata"].get("annotations") or {})


def pod_members(manifest: dict[str, Any]) -> list[tuple[str, str]]:
    """(component, role) of every component the pod runs, in startup order."""
    metadata = manifest["metadata"]
    members = (metadata.get("annotations") or {}).get(names.ANNOTATION_COMPONENTS)
    if members is None:
        return [(metadata["labels"][names.LABEL_COMPONENT], metadata["labels"][names.LABEL_ROLE])]
    # Written by the operator, but a pod's annotations are anyone's with `patch pods`: an entry
    # that is not `role:name` is no component.
    pairs = [member.split(":", 1) for member in str(members).split(",") if member.count(":") == 1]
    return [(name, role) for role, name in pairs]


def owner_reference(api_version: str, kind: str, name: str, uid: str) -> dict[str, Any]:
    """A controller owner reference, so deleting the owner deletes the object (garbage collection)."""
    return {"apiVersion": api_version, "kind": kind, "name": name, "uid": uid, "controller": True}
