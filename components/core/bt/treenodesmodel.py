"""Node models as a BT.CPP `<TreeNodesModel>` document, the palette Groot2 reads.

Built with ElementTree and laid out as BT.CPP's `writeTreeNodesModelXML` (xml_parsing.cpp) writes
it through tinyxml2: `<root BTCPP_format="4">`, models sorted by ID, ports grouped by direction
(input, output, inout) and sorted by name, 4-space indentation, `<Action ID="X"/>` for a node
without ports, and type names as BT.CPP demangles them (`std::string`, `BT::AnyTypeAllowed`,
`std::vector<double>`). Pure; the one writer of the format: `NodeRegistry.tree_nodes_model_xml`
passes its node specs, `coral nodes-model` and `coral plugins model` the behaviors of plugin
manifests (both have the fields of `NodeModel`).
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from typing import Protocol

_ELEMENT_OF_KIND = {
    "action": "Action",
    "condition": "Condition",
    "control": "Control",
    "decorator": "Decorator",
    "subtree": "SubTree",
}
_PORT_ELEMENT = {"input": "input_port", "output": "output_port", "inout": "inout_port"}
_DIRECTION_ORDER = {"input": 0, "output": 1, "inout": 2}
# Declared spellings (Python-side or short) -> what BT::demangle prints for the C++ type.
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


class PortModel(Protocol):
    name: str
    direction: str
    type: str
    default: str | None
    description: str


class NodeModel(Protocol):
    id: str
    kind: str
    ports: Sequence[PortModel]


def cpp_type_name(declared: str) -> str:
    """The type name BT.CPP would write for a port declared as `declared` (C++ names pass through)."""
    text = (declared or "").strip()
    listed = _LIST.match(text)
    if listed:
        return f"std::vector<{cpp_type_name(listed.group('py') or listed.group('colon'))}>"
    return _CPP_TYPE.get(text.lower(), text)


def build_tree_nodes_model(nodes: Iterable[NodeModel]) -> str:
    """A `<root BTCPP_format="4"><TreeNodesModel>` document listing `nodes` sorted by ID (nodes with
    the same ID keep the order they came in)."""
    root = ET.Element("root", {"BTCPP_format": "4"})
    model = ET.SubElement(root, "TreeNodesModel")
    for node in sorted(nodes, key=lambda n: n.id):
        element = ET.SubElement(model, _ELEMENT_OF_KIND[str(node.kind)], {"ID": node.id})
        for port in sorted(node.ports, key=lambda p: (_DIRECTION_ORDER[str(p.direction)], p.name)):
            attributes = {"name": port.name, "type": cpp_type_name(port.type)}
            if port.default is not None and port.default != "":
                attributes["default"] = port.default
            ET.SubElement(element, _PORT_ELEMENT[str(port.direction)], attributes).text = (
                port.description or None
            )
    ET.indent(root, space="    ")
    # ElementTree closes empty elements as `<X />`, tinyxml2 as `<X/>`; attribute values and text
    # are escaped (`>` becomes `&gt;`), so " />" can only be the end of a tag.
    return ET.tostring(root, encoding="unicode").replace(" />", "/>") + "\n"
