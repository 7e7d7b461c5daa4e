"""CoralSystems at their admitted maximum, for the memory and load tests.

Parameters and tree just under the inline limit (`api.system.MAX_INLINE_BYTES`), and every tree
file the schema admits at its own limit, all of them valid: what a tenant may make the operator
hold and validate with no refusal.
"""

from __future__ import annotations

import copy
from typing import Any

from coral_api import fleet_mission
from coral_operator.api.system import MAX_INLINE_BYTES, MAX_TREE_FILE_BYTES, MAX_TREE_FILES

# Room for the YAML and JSON around a field: the limit is on the field's characters.
_MARGIN = 64


def parameters(salt: str, size: int = MAX_INLINE_BYTES - _MARGIN) -> str:
    """Valid ROS parameters of about `size` characters: nodes of forty values each, no alias."""
    parts, total, node = [], 0, 0
    while True:
        block = f"node_{salt}_{node}:\n  ros__parameters:\n" + "".join(
            f"    gain_{j}: {node}.{j}\n" for j in range(40)
        )
        if total + len(block) > size:
            break
        parts.append(block)
        total += len(block)
        node += 1
    return "".join(parts)


def _padded(document: str, size: int, salt: str) -> str:
    """`document` (XML) grown to `size` characters by a comment after its root element's start."""
    head, rest = document.split(">", 1)
    filler = size - len(document) - len("<!--  -->") - len(salt) - 1
    return f"{head}><!-- {salt} {'x' * max(filler, 0)} -->{rest}"


def tree(base: str, salt: str, size: int = MAX_INLINE_BYTES - _MARGIN) -> str:
    return _padded(base, size, salt)


def tree_files(salt: str) -> dict[str, str]:
    """Every tree file the schema admits, each at its size limit; valid, though nothing includes them."""
    file = '<root BTCPP_format="4">\n  <BehaviorTree ID="Spare"><AlwaysSuccess/></BehaviorTree>\n</root>\n'
    return {
        f"spare{i}.xml": _padded(file, MAX_TREE_FILE_BYTES - _MARGIN, salt) for i in range(MAX_TREE_FILES)
    }


def maximal_system(name: str, fleet: str, salt: str = "") -> dict[str, Any]:
    """The fleet mission with parameters, tree and tree files at their admitted maximum; its own
    content (salted by `name` and `salt`), so no two are validated as one."""
    manifest = copy.deepcopy(fleet_mission(name, fleet))
    spec = manifest["spec"]
    salt = f"{name}_{salt}".replace("-", "_")
    spec["parameters"] = {"inline": parameters(salt)}
    spec["tree"]["inline"] = tree(spec["tree"]["inline"], salt)
    spec["tree"]["files"] = tree_files(salt)
    return manifest
