"""Validates the tree XML and the parameters YAML before anything reaches a robot (docs/architecture.md).

Errors read `file:line: message`. The tree goes through the BT engine (`coral_core.bt`), the same
loader the executors use, with two differences that keep one namespace's bad input from costing
the operator anything: the text is first checked against `TreeLimits` (size, element count, depth,
entity declarations) by a scan that holds only counters, and `<include>`s resolve only among the
files the CoralSystem carries (`spec.tree.files`), never from the operator's filesystem. Any other
exception is turned into a problem, never raised. The parameters are measured on the parser's
event stream (`coral_core.parsing.check_yaml`) and never built: the operator only copies them into a
ConfigMap. Given a `Verdicts` table, results are remembered by content hash, since every system
pass validates again what rarely changes. Called by the system handler and `coral convert`; pure.
"""

from __future__ import annotations

import hashlib
import posixpath
import re
import threading
from collections import OrderedDict
from collections.abc import Callable, Mapping

import yaml
from coral_core import bt, parsing
from coral_core.bt.limits import IncludeBudget, TreeLimits, check_document
from coral_core.bt.loader import IncludeResolver

LIMITS = TreeLimits()
VERDICTS_KEPT = 2048
"""Validation verdicts remembered (each at most `PROBLEMS_SHOWN` messages, keyed by a hash): more
than the systems a pass loop revisits while their files stay the same."""
PROBLEMS_SHOWN = 20
"""Problems a status message shows; the rest are counted (`planning.system_pass.listed`)."""
VALIDATIONS_AT_ONCE = 2


class Verdicts:
    """Problems by content hash, least recently used dropped first; thread safe. One per process
    (`reconcile.memory.Memory.verdicts`).

    At most `VALIDATIONS_AT_ONCE` validations run at a time: each holds a document model of up to
    tens of MB while it runs (a 256 KiB tree of 16,000 elements: 8 MB), and validation is CPU
    work under one interpreter lock, so the queue's 32 workers would gain no time by running
    more, only hold more memory at once.
    """

    def __init__(self, size: int = VERDICTS_KEPT) -> None:
        self._size = size
        self._running = threading.BoundedSemaphore(VALIDATIONS_AT_ONCE)
        self._lock = threading.Lock()
        self._kept: OrderedDict[str, list[str]] = OrderedDict()

    def get(self, parts: tuple[object, ...], compute: Callable[[], list[str]]) -> list[str]:
        key = hashlib.sha256(repr(parts).encode("utf-8", "surrogatepass")).hexdigest()
        with self._lock:
            if key in self._kept:
                self._kept.move_to_end(key)
                return list(self._kept[key])
        with self._running:
            problems = compute()
        with self._lock:
            # Only what a message shows, and how many more: a tree can have thousands of problems.
            self._kept[key] = problems[:PROBLEMS_SHOWN] + [""] * (len(problems) - PROBLEMS_SHOWN)
            while len(self._kept) > self._size:
                self._kept.popitem(last=False)
        return problems


def _computed(parts: tuple[object, ...], compute: Callable[[], list[str]]) -> list[str]:
    return compute()


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
    verdicts: Verdicts | None = None,
) -> list[str]:
    """Problems of a BT.CPP XML document, each `file:line: message`; empty when it is valid.

    The engine's own loader reads the XML as BT.CPP does (raw `&&` and `<` in scripts are
    valid there), so a tree the robots would run is never refused here. Node types are not
    checked against plugins: only the robot knows which skillsets run.
    """
    parts = ("tree", text, filename, main_tree_id, sorted((files or {}).items()), limits, files_label)
    return (verdicts.get if verdicts is not None else _computed)(
        parts, lambda: _validate_tree(text, filename, main_tree_id, files or {}, limits, files_label)
    )


def _validate_tree(
    text: str,
    filename: str,
    main_tree_id: str | None,
    files: Mapping[str, str],
    limits: TreeLimits,
    files_label: str,
) -> list[str]:
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
        for error in bt.validate_document(document, registry)
        if not any(re.search(rf"\b{re.escape(node)}\b", str(error)) for node in plugin_nodes)
    ]


def validate_parameters(text: str, filename: str, verdicts: Verdicts | None = None) -> list[str]:
    """Problems of a ROS parameters YAML, each `file:line: message`; empty when it is valid.

    Aliases, merge keys, the expanded size and the nesting are bounded (`parsing.PARAMETER_LIMITS`,
    the same bounds the robot's `coral.sdk.params` applies), so a few hundred bytes cannot stand
    for millions of entries; a refusal names the figure and the limit.
    """
    parts = ("parameters", text, filename)
    return (verdicts.get if verdicts is not None else _computed)(
        parts, lambda: _validate_parameters(text, filename)
    )


def _validate_parameters(text: str, filename: str) -> list[str]:
    try:
        root = parsing.check_yaml(text, parsing.PARAMETER_LIMITS)
    except parsing.OverLimit as error:
        line = error.problem_mark.line + 1 if error.problem_mark else 1
        return [f"{filename}:{line}: {error.problem}"]
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        line = mark.line + 1 if mark else 1
        return [f"{filename}:{line}: invalid YAML: {error.problem or error}"]
    except yaml.YAMLError as error:
        return [f"{filename}:1: invalid YAML: {error}"]
    except Exception as error:  # noqa: BLE001 - one bad document must never stop the operator
        return [f"{filename}:1: the parameters could not be read ({type(error).__name__})"]
    if root == "sequence":
        return [f"{filename}:1: parameters must be a mapping of node names, got list"]
    if root == "scalar":
        # One scalar, whatever its size, is cheap to build; a null one means no parameters. The
        # loader's scanner can still refuse what the event parser let through (a trailing tab).
        try:
            document = parsing.load_yaml(text)
        except yaml.YAMLError as error:
            return [f"{filename}:1: invalid YAML: {getattr(error, 'problem', None) or error}"]
        if document is not None:
            return [
                f"{filename}:1: parameters must be a mapping of node names, got {type(document).__name__}"
            ]
    return []
