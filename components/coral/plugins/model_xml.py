"""Renders manifests as a BT.CPP `<TreeNodesModel>` so Groot2 users get a palette of exported nodes.

Built with ElementTree and laid out as BT.CPP's `writeTreeNodesModelXML` (xml_parsing.cpp) writes
it through tinyxml2: `<root BTCPP_format="4">`, models sorted by ID, ports grouped by direction
(input, output, inout) and sorted by name, 4-space indentation, `<Action ID="X"/>` for a node
without ports, and type names as BT.CPP demangles them (`std::string`, `BT::AnyTypeAllowed`,
`std::vector<double>`). Pure; called by `coral nodes-model`, `coral plugins model` and tests.
"""

from __future__ import annotations

import re
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
_DIRECTION_ORDER = {"input": 0, "output": 1, "inout": 2}
# Manifest spellings (Python-side or short) -> what BT::demangle prints for the C++ type.
_CPP_TYPE = {
    "": "BT::AnyTypeAllowed",
    "any": "BT::AnyTypeAllowed",
    "object": "BT::AnyTypeAllowed",
    "anytypeallowed": "BT::AnyTypeAllowed",
    "string": "std::string",
    "str": "std::string",
    "script": "std::string",
    "float": "float",
    "nodestatus": "BT::NodeStatus",
    "status": "BT::NodeStatus",
}
_LIST = re.compile(r"^(?:list\[(?P<py>.*)\]|list:(?P<colon>.*))$", re.IGNORECASE)


def cpp_type_name(declared: str) -> str:
    """The type name BT.CPP would write for a port declared as `declared` (C++ names pass through)."""
    text = (declared or "").strip()
    listed = _LIST.match(text)
    if listed:
        return f"std::vector<{cpp_type_name(listed.group('py') or listed.group('colon'))}>"
    return _CPP_TYPE.get(text.lower(), text)


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
        for port in sorted(behavior.ports, key=lambda p: (_DIRECTION_ORDER[p.direction], p.name)):
            attributes = {"name": port.name, "type": cpp_type_name(port.type)}
            if port.default is not None and port.default != "":
                attributes["default"] = port.default
            element = ET.SubElement(node, _PORT_ELEMENT[port.direction], attributes)
            if port.description:
                element.text = port.description
    ET.indent(root, space="    ")
    # ElementTree closes empty elements as `<X />`, tinyxml2 as `<X/>`; attribute values and text
    # are escaped (`>` becomes `&gt;`), so " />" can only be the end of a tag.
    return ET.tostring(root, encoding="unicode").replace(" />", "/>") + "\n"
