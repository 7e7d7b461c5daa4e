"""The BLACKBOARD reply: named subtree boards as MessagePack, as BT.CPP 4.10's
`generateBlackboardsDump` builds them with `ExportBlackboardToJSON` and `json::to_msgpack`.

Called on the publisher's server thread while the tree may be ticking: it copies each board's
entries in one step (`list(dict.items())` runs without releasing the GIL) and never takes the
tree's lock, so a dump never waits for a tick and a tick never waits for a dump.
"""

from __future__ import annotations

from typing import Any

import msgpack
from coral_core.bt.anyvalue import EMPTY
from coral_core.bt.groot2.fulltree import SubtreeInstance
from coral_core.bt.groot2.protocol import ProtocolError

ROOT_NAME = "ROOT"


def export_value(value: Any) -> Any:
    """What `JsonExporter::toJson` gives: numbers and text as themselves (a bool is an int64 in
    `BT::Any`), vectors of them as arrays, anything else (an empty entry, a queue) as null."""
    if value is EMPTY:
        return None
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, (int, float, str)):
        return value
    if isinstance(value, (list, tuple)):
        items = list(value)
        if all(isinstance(v, (int, float, str)) for v in items):
            return [int(v) if isinstance(v, bool) else v for v in items]
    return None


def export_board(board: Any) -> dict[str, Any] | None:
    """The local entries (not the remapped ones); an empty board is JSON null, as in BT.CPP."""
    entries = list(board.storage.items())
    if not entries:
        return None
    return {key: export_value(entry.value) for key, entry in entries}


def dump_boards(names_text: str, instances: dict[str, SubtreeInstance], root_board: Any) -> bytes:
    """The dump of the boards named in `names_text` (separated by ';'; unknown names are left out).

    4.10 adds the root board as "ROOT" whenever a named board is not the root itself (4.8.2 does
    not), and refuses a request that would make "ROOT" ambiguous.
    """
    dump: dict[str, Any] = {}
    root_exported = False
    for name in names_text.split(";"):
        instance = instances.get(name)
        if instance is None:
            continue
        needs_root = instance.board is not root_board
        if name == ROOT_NAME and (needs_root or root_exported):
            raise ProtocolError(
                "blackboard dump request uses reserved name [ROOT] together with an external "
                "root blackboard export"
            )
        dump[name] = export_board(instance.board)
        if needs_root and not root_exported:
            if ROOT_NAME in dump:
                raise ProtocolError(
                    "blackboard dump request would overwrite subtree [ROOT] with an external root "
                    "blackboard export"
                )
            dump[ROOT_NAME] = export_board(root_board)
            root_exported = True
    return msgpack.packb(dump or None, use_bin_type=True)
