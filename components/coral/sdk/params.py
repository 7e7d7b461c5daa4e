"""ROS 2 parameters YAML: validation with file:line errors, and the `--params-file` matching rules.

rcl applies the file itself (components pass `--ros-args --params-file`); this module checks it
first so a bad file fails with a readable message, and resolves the parameters one node would
get (`/**` and `*` wildcards) for tools and tests. Called by `coral.sdk.running` and the executor.
"""

from __future__ import annotations

import fnmatch
import re
from pathlib import Path
from typing import Any

import yaml
from coral_core import parsing

PARAMS_KEY = "ros__parameters"


class ParamsError(ValueError):
    """A parameters file that rcl would reject; `str()` reads `file:line: message`."""


def _where(path: str, node: yaml.Node) -> str:
    return f"{path}:{node.start_mark.line + 1}"


def _check_values(path: str, node: yaml.Node, prefix: str) -> None:
    if not isinstance(node, yaml.MappingNode):
        raise ParamsError(f"{_where(path, node)}: '{prefix}' must be a mapping of parameter names to values")
    for key_node, value_node in node.value:
        name = f"{prefix}.{key_node.value}" if prefix != PARAMS_KEY else key_node.value
        if isinstance(value_node, yaml.MappingNode):
            _check_values(path, value_node, name)
        elif isinstance(value_node, yaml.SequenceNode):
            kinds = {type(item) for item in value_node.value}
            if kinds - {yaml.ScalarNode}:
                raise ParamsError(
                    f"{_where(path, value_node)}: parameter '{name}' arrays may hold scalars only"
                )


def _check_node_entry(path: str, key: str, node: yaml.Node) -> None:
    if not isinstance(node, yaml.MappingNode):
        raise ParamsError(f"{_where(path, node)}: entry '{key}' must be a mapping")
    keys = [key_node.value for key_node, _ in node.value]
    if PARAMS_KEY in keys:
        for key_node, value_node in node.value:
            if key_node.value == PARAMS_KEY:
                _check_values(path, value_node, PARAMS_KEY)
            else:
                raise ParamsError(
                    f"{_where(path, key_node)}: unexpected key '{key_node.value}' "
                    f"beside '{PARAMS_KEY}' in '{key}'"
                )
        return
    if not keys:
        raise ParamsError(f"{_where(path, node)}: entry '{key}' has no '{PARAMS_KEY}'")
    # Nested namespaces: `ns: {node: {ros__parameters: ...}}`.
    for key_node, value_node in node.value:
        _check_node_entry(path, f"{key}/{key_node.value}", value_node)


def validate_text(text: str, path: str = "<params>") -> dict[str, Any]:
    """Checks a parameters document and returns it parsed; raises `ParamsError` naming file and line.

    The document is measured first (`parsing.check_yaml` with the operator's bounds on aliases,
    merge keys, expanded size and nesting), so nothing is built from one that expands past them.
    """
    try:
        parsing.check_yaml(text, parsing.PARAMETER_LIMITS)
    except parsing.OverLimit as err:
        line = f":{err.problem_mark.line + 1}" if err.problem_mark is not None else ""
        raise ParamsError(f"{path}{line}: {err.problem}") from err
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        line = f":{mark.line + 1}" if mark is not None else ""
        raise ParamsError(f"{path}{line}: invalid YAML: {getattr(err, 'problem', err)}") from err
    try:
        root = parsing.compose_yaml(text)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        line = f":{mark.line + 1}" if mark is not None else ""
        raise ParamsError(f"{path}{line}: invalid YAML: {getattr(err, 'problem', err)}") from err
    if root is None:
        return {}
    if not isinstance(root, yaml.MappingNode):
        raise ParamsError(f"{_where(path, root)}: a parameters file must map node names to '{PARAMS_KEY}'")
    for key_node, value_node in root.value:
        _check_node_entry(path, str(key_node.value), value_node)
    return parsing.load_yaml(text) or {}


def validate_file(path: Path) -> dict[str, Any]:
    try:
        text = parsing.read_text(path)
    except OSError as err:
        raise ParamsError(f"{path}: cannot read parameters file: {err.strerror}") from err
    except parsing.NotText as err:
        raise ParamsError(f"{path}:{err.line}: {err.reason}") from err
    return validate_text(text, str(path))


def _pattern_regex(pattern: str) -> re.Pattern[str]:
    """rcl's node-name wildcards: `**` spans any number of tokens, `*` exactly one."""
    if not pattern.startswith("/"):
        pattern = "/" + pattern
    parts = []
    for token in pattern.strip("/").split("/"):
        if token == "**":
            parts.append("(?:/[^/]+)*")
        else:
            parts.append(
                "/"
                + fnmatch.translate(token).removeprefix("(?s:").removesuffix(")\\Z").replace(".*", "[^/]*")
            )
    return re.compile("^" + "".join(parts) + "$")


def _flatten(entries: dict[str, Any], prefix: str = "") -> list[tuple[str, dict[str, Any]]]:
    flat: list[tuple[str, dict[str, Any]]] = []
    for key, value in entries.items():
        name = f"{prefix}/{key}".replace("//", "/")
        if isinstance(value, dict) and PARAMS_KEY in value:
            flat.append((name, value[PARAMS_KEY] or {}))
        elif isinstance(value, dict):
            flat.extend(_flatten(value, name))
    return flat


def _dotted(values: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in values.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, dict):
            out.update(_dotted(value, name))
        else:
            out[name] = value
    return out


def parameters_for(document: dict[str, Any], node_fqn: str) -> dict[str, Any]:
    """Parameters (dotted names) a node with fully qualified name `node_fqn` gets; later entries win."""
    resolved: dict[str, Any] = {}
    for pattern, values in _flatten(document):
        if _pattern_regex(pattern).match(node_fqn):
            resolved.update(_dotted(values))
    return resolved
