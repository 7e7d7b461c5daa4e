"""Validates the tree XML and the parameters YAML before anything reaches a robot (DESIGN section 9).

Errors read `file:line: message`. The tree goes through the BT engine (`coral.bt`), the same
loader the executors use. Called by the system handler and `coral convert`; pure.
"""

from __future__ import annotations

import re

import yaml
from coral import bt


def validate_tree(text: str, filename: str, main_tree_id: str | None = None) -> list[str]:
    """Problems of a BT.CPP XML document, each `file:line: message`; empty when it is valid.

    The engine's own loader reads the XML as BT.CPP does (raw `&&` and `<` in scripts are
    valid there), so a tree the robots would run is never refused here. Node types are not
    checked against plugins: only the robot knows which skillsets run.
    """
    try:
        document = bt.load_tree_text(text, filename=filename, main_tree=main_tree_id)
    except bt.BTLoadError as error:
        return [_located(error, filename)]
    return _static_problems(document, filename)


def _located(error: Exception, filename: str) -> str:
    return str(error) if str(error).startswith(filename) else f"{filename}: {error}"


def _static_problems(document: bt.TreeDocument, filename: str) -> list[str]:
    """Problems the engine finds with only its built-in nodes known, minus those about plugin nodes:
    which plugins exist is only known on the robot, where the executor checks the rest."""
    registry = bt.NodeRegistry.with_builtins()
    plugin_nodes = set(document.missing_node_types(registry))
    return [
        _located(error, filename)
        for error in document.validate(registry)
        if not any(re.search(rf"\b{re.escape(node)}\b", str(error)) for node in plugin_nodes)
    ]


def validate_parameters(text: str, filename: str) -> list[str]:
    """Problems of a ROS parameters YAML, each `file:line: message`; empty when it is valid."""
    try:
        document = yaml.safe_load(text)
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        line = mark.line + 1 if mark else 1
        return [f"{filename}:{line}: invalid YAML: {error.problem or error}"]
    except yaml.YAMLError as error:
        return [f"{filename}:1: invalid YAML: {error}"]
    if document is not None and not isinstance(document, dict):
        return [f"{filename}:1: parameters must be a mapping of node names, got {type(document).__name__}"]
    return []
