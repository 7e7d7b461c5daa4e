"""Builds real plugin folders for tests, the way a component's export would, without ROS."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import coral
from coral.plugins import compat, hashing
from coral.plugins import manifest as manifests

GREETER_SOURCE = """
from coral_core.bt import PortDirection, PortSpec, Status
from coral_core.bt.leaves import SyncAction


class {cls}(SyncAction):
    PORTS = [PortSpec("greeting", PortDirection.OUTPUT, "string")]

    def tick(self) -> Status:
        self.set_output("greeting", "{text}")
        return Status.SUCCESS
"""


def write_plugin(
    root: Path,
    name: str,
    modules: dict[str, str],
    behaviors: list[dict[str, Any]],
    interfaces: dict[str, str] | None = None,
    **overrides: Any,
) -> Path:
    """Writes `<root>/<name>/` with `behaviors/<module>.py` files, optional `interfaces/<package>/`
    packages (name -> `__init__.py` source) and a correctly hashed manifest."""
    folder = root / name
    for package, source in (interfaces or {}).items():
        (folder / manifests.INTERFACES_DIR / package).mkdir(parents=True)
        (folder / manifests.INTERFACES_DIR / package / "__init__.py").write_text(source)
    (folder / manifests.BEHAVIORS_DIR).mkdir(parents=True)
    (folder / manifests.BEHAVIORS_DIR / "__init__.py").write_text("")
    for module, source in modules.items():
        (folder / manifests.BEHAVIORS_DIR / f"{module}.py").write_text(source)
    manifest: dict[str, Any] = {
        "schema_version": manifests.SCHEMA_VERSION,
        "component": {"name": name, "kind": "skillset", "node_name": name, "namespace": "/"},
        "coral_version": coral.__version__,
        "ros_distro": compat.current_ros_distro(),
        "behaviors": behaviors,
        "files": hashing.hash_tree(folder),
        "interface_packages": sorted(interfaces or {}),
    }
    manifest.update(overrides)
    (folder / manifests.MANIFEST_NAME).write_text(json.dumps(manifest, indent=2))
    return folder


def greeter_plugin(root: Path, name: str, node_id: str, text: str, module: str = "behaviors") -> Path:
    """A plugin exporting one synchronous action `node_id` that writes `text` to its `greeting` port."""
    return write_plugin(
        root,
        name,
        {module: GREETER_SOURCE.format(cls=node_id, text=text)},
        [
            {
                "id": node_id,
                "kind": "action",
                "module": module,
                "class": node_id,
                "ports": [{"name": "greeting", "direction": "output", "type": "string"}],
            }
        ],
    )
