"""Export of registered node types as a Groot2-compatible `<TreeNodesModel>` document."""

from __future__ import annotations

from typing import TYPE_CHECKING
from xml.sax.saxutils import escape, quoteattr

from coral.bt.status import NodeKind, PortDirection

if TYPE_CHECKING:
    from coral.bt.registry import NodeRegistry

_TAG = {
    NodeKind.ACTION: "Action",
    NodeKind.CONDITION: "Condition",
    NodeKind.CONTROL: "Control",
    NodeKind.DECORATOR: "Decorator",
    NodeKind.SUBTREE: "SubTree",
}
_PORT_TAG = {
    PortDirection.INPUT: "input_port",
    PortDirection.OUTPUT: "output_port",
    PortDirection.INOUT: "inout_port",
}


def registry_to_xml(registry: NodeRegistry, only_plugins: bool = True) -> str:
    from coral.bt.registry import BUILTIN_SOURCE, V3_SOURCE

    lines = ['<root BTCPP_format="4">', "  <TreeNodesModel>"]
    for node_id in registry.node_ids():
        spec = registry.spec(node_id)
        if only_plugins and spec.source in (BUILTIN_SOURCE, V3_SOURCE):
            continue
        tag = _TAG[spec.kind]
        if not spec.ports:
            lines.append(f"    <{tag} ID={quoteattr(node_id)}/>")
            continue
        lines.append(f"    <{tag} ID={quoteattr(node_id)}>")
        for p in spec.ports:
            attrs = f"name={quoteattr(p.name)} type={quoteattr(p.type)}"
            if p.default is not None:
                attrs += f" default={quoteattr(p.default)}"
            ptag = _PORT_TAG[PortDirection(p.direction)]
            if p.description:
                lines.append(f"      <{ptag} {attrs}>{escape(p.description)}</{ptag}>")
            else:
                lines.append(f"      <{ptag} {attrs}/>")
        lines.append(f"    </{tag}>")
    lines += ["  </TreeNodesModel>", "</root>", ""]
    return "\n".join(lines)
