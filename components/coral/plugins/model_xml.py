"""Renders manifests as a BT.CPP `<TreeNodesModel>` so Groot2 users get a palette of exported nodes.

Pure; called by the `coral plugins model` verb and by tests.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterable

from coral.plugins import manifest as manifests

_ELEMENT_OF_KIND = {
    "action": "Action",
    "condition": "Condition",
    "control": "Control",
    "decorator": "Decorator",
}
_PORT_ELEMENT = {"input": "input_port", "output": "output_port", "inout": "inout_port"}


def build_tree_nodes_model(plugins: Iterable[manifests.PluginManifest]) -> str:
    """A `<root BTCPP_format="4"><TreeNodesModel>` document listing every behavior, sorted by ID."""
    root = ET.Element("root", {"BTCPP_format": "4"})
    model = ET.SubElement(root, "TreeNodesModel")
    entries = sorted(
        ((behavior, plugin.component.name) for plugin in plugins for behavior in plugin.behaviors),
        key=lambda pair: (pair[0].id, pair[1]),
    )
    for behavior, _component in entries:
        node = ET.SubElement(model, _ELEMENT_OF_KIND[behavior.kind], {"ID": behavior.id})
        for port in behavior.ports:
            attributes = {"name": port.name, "type": port.type}
            if port.default is not None:
                attributes["default"] = port.default
            element = ET.SubElement(node, _PORT_ELEMENT[port.direction], attributes)
            if port.description:
                element.text = port.description
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"
