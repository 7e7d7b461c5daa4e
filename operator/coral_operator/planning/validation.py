"""Validates the tree XML and the parameters YAML before anything reaches a robot (docs/architecture.md).

Errors read `file:line: message`. The tree goes through the BT engine (`coral.bt`), the same
loader the executors use, with two differences that keep one namespace's bad input from costing
the operator anything: the text is first checked against `TreeLimits` (size, element count, depth,
entity declarations) by a scan that holds only counters, and `<include>`s resolve only among the
files the CoralSystem carries (`spec.tree.files`), never from the operator's filesystem. Any other
exception is turned into a problem, never raised. Called by the system handler and `coral
convert`; pure.
"""

from __future__ import annotations

import posixpath
import re
from collections.abc import Mapping

import yaml
from coral import bt, parsing
from coral.bt.limits import IncludeBudget, TreeLimits, check_document
from coral.bt.loader import IncludeResolver

LIMITS = TreeLimits()


def include_resolver(files: Mapping[str, str], budget: IncludeBudget, label: str) -> IncludeResolver:
    """Resolves `<include path=...>` among `files` (by name) only, each checked against `budget`.

    A refusal says which names exist and nothing about any filesystem.
    """

    def resolve(path: str, including: str, line: int) -> tuple[str, str]:
        budget.count_include(including, line)
        name = posixpath.normpath(path.strip()) if path.strip() else ""
        if name not in files or name.startswith("/"):
            known = ", ".join(sorted(files)) or "none"
            raise bt.BTLoadError(
                f"<include path={path[:200]!r}> names no file of this CoralSystem; includes resolve "
                f"only among spec.tree.files (given: {known})",
                file=including,
                line=line,
            )
        included = f"{label}[{name}]"
        check_document(files[name], included, budget)
        return included, files[name]

    return resolve


def validate_tree(
    text: str,
    filename: str,
    main_tree_id: str | None = None,
    files: Mapping[str, str] | None = None,
    limits: TreeLimits = LIMITS,
    files_label: str = "spec.tree.files",
) -> list[str]:
    """Problems of a BT.CPP XML document, each `file:line: message`; empty when it is valid.

    The engine's own loader reads the XML as BT.CPP does (raw `&&` and `<` in scripts are
    valid there), so a tree the robots would run is never refused here. Node types are not
    checked against plugins: only the robot knows which skillsets run.
    """
    budget = IncludeBudget(limits)
    try:
        check_document(text, filename, budget)
        document = bt.load_tree_text(
            text,
            filename=filename,
            main_tree=main_tree_id,
            resolve_include=include_resolver(files or {}, budget, files_label),
        )
        return _static_problems(document, filename)
    except bt.BTLoadError as error:
        return [_located(error, filename)]
    except RecursionError:
        # Element depth is bounded above; what is left is an expression nested past Python's stack.
        return [f"{filename}: an expression (a script or port value) nests too deeply to be read"]
    except Exception as error:  # noqa: BLE001 - one bad tree must never stop the operator
        return [f"{filename}: the tree could not be validated ({type(error).__name__})"]


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
        document = parsing.load_yaml(text)
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        line = mark.line + 1 if mark else 1
        return [f"{filename}:{line}: invalid YAML: {error.problem or error}"]
    except yaml.YAMLError as error:
        return [f"{filename}:1: invalid YAML: {error}"]
    except Exception as error:  # noqa: BLE001 - one bad document must never stop the operator
        return [f"{filename}:1: the parameters could not be read ({type(error).__name__})"]
    if document is not None and not isinstance(document, dict):
        return [f"{filename}:1: parameters must be a mapping of node names, got {type(document).__name__}"]
    return []
