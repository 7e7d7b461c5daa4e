"""One robot's effective configuration: the system's spec with the overrides that match it resolved.

Pure: `effective_config(base, overrides, robot)` gives what the robot runs or a `ConfigError` naming
the robot and the field. The rules (docs/overrides.md), stated once here:

- Precedence: the system's spec, then every override whose selector matches the robot, then the
  robot's Node values substituted into the overrides' values.
- Matching overrides never outrank each other: two that set the same field (a parameter leaf, an
  env variable, a component's image, a tree file, the main tree) to different values conflict,
  and the robot's configuration is an error naming both. Equal values agree.
- Order within the resolution: components removed, then added, then images and env applied to
  the result (so they reach added components), then parameters deep-merged (mappings key by key,
  anything else replaced), then tree documents replaced by name.
- `${robot.name}`, `${robot.labels['KEY']}` and `${robot.annotations['KEY']}` are substituted in
  the overrides' parameter strings, env values and images (`planning.node_values`); `$${` stands
  for a literal `${`. A missing key is an error naming the robot, the field and the key.

Called by `planning.effective` (the system pass) and `coral config`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import yaml
from coral_core import parsing
from pydantic import ValidationError

from coral_operator.api.components import Component, EnvVar, ExecutorComponent
from coral_operator.api.overrides import Override
from coral_operator.api.system import CoralSystemSpec, groot2_ports_overlap
from coral_operator.planning import selection
from coral_operator.planning.node_values import Unresolved, substitute, substitute_values
from coral_operator.planning.observed import RobotNode

KINDS = ("drivers", "skillsets", "executors")
CONFLICT = "conflicts with override {other}, which also matches this robot and sets it differently"


@dataclass(frozen=True)
class ConfigError:
    """Why one robot has no valid effective configuration."""

    robot: str
    field: str
    """The spec field at fault, for example `spec.overrides[spot].env[ROBOT_IP]`."""
    message: str

    def __str__(self) -> str:
        return f"robot {self.robot}: {self.field}: {self.message}"


@dataclass(frozen=True)
class RobotConfiguration:
    """The files and components a robot runs: the system's (`BaseConfig`) or one robot's
    (`EffectiveConfig`)."""

    tree: str
    tree_files: Mapping[str, str]
    main_tree_id: str | None
    parameters: str
    drivers: Sequence[Component]
    skillsets: Sequence[Component]
    executors: Sequence[ExecutorComponent]


@dataclass(frozen=True)
class BaseConfig(RobotConfiguration):
    """What every robot runs before overrides: the system's validated files and components."""

    @classmethod
    def of_spec(cls, spec: CoralSystemSpec, tree: str, parameters: str) -> BaseConfig:
        return cls(
            tree=tree,
            tree_files=dict(spec.tree.files),
            main_tree_id=spec.tree.main_tree_id,
            parameters=parameters,
            drivers=spec.drivers,
            skillsets=spec.skillsets,
            executors=spec.executors,
        )


@dataclass(frozen=True)
class EffectiveConfig(RobotConfiguration):
    """What one robot runs."""

    applied: tuple[str, ...] = ()
    """Names of the overrides that match the robot, in spec order."""
    changed: frozenset[str] = field(default_factory=frozenset)
    """Which of `tree` and `parameters` differ from the system's (they need validating again)."""


class _Claims:
    """Values set by overrides, by the field they set: a second, different value is a conflict."""

    def __init__(self) -> None:
        self._by_field: dict[str, tuple[str, Any]] = {}

    def claim(self, owner: str, what: str, value: Any) -> None:
        known = self._by_field.get(what)
        if known is not None and known[0] != owner and known[1] != value:
            raise Unresolved(f"spec.overrides[{owner}].{what}", CONFLICT.format(other=known[0]))
        self._by_field.setdefault(what, (owner, value))

    def items(self) -> list[tuple[str, str, Any]]:
        return [(what, owner, value) for what, (owner, value) in self._by_field.items()]


def effective_config(
    base: BaseConfig,
    overrides: Sequence[Override],
    robot: RobotNode,
    parsed: ParsedDocuments | None = None,
) -> EffectiveConfig | ConfigError:
    """The configuration `robot` runs, or why it has none (see the module docstring for the rules).

    Only the composition is checked here; the changed tree and parameters documents are validated
    by `planning.effective`, as the system's own are. `parsed` shares parsed documents between
    the robots of one pass.
    """
    matching = [o for o in overrides if selection.matches(o.robots, robot.labels)]
    try:
        components = _components(base, matching, robot)
        parameters, params_changed = _parameters(
            base.parameters, matching, robot, parsed or ParsedDocuments()
        )
        tree, files, main_tree_id = _tree(base, matching)
    except Unresolved as error:
        return ConfigError(robot.robot, error.where, error.message)
    problem = _composition_problem(components)
    if problem is not None:
        return ConfigError(robot.robot, *problem)
    return EffectiveConfig(
        tree=tree,
        tree_files=files,
        main_tree_id=main_tree_id,
        parameters=parameters,
        drivers=components["drivers"],
        skillsets=components["skillsets"],
        executors=components["executors"],  # type: ignore[arg-type]
        applied=tuple(o.name for o in matching),
        changed=frozenset({"parameters"} if params_changed else set())
        | (
            {"tree"}
            if (tree, files, main_tree_id) != (base.tree, dict(base.tree_files), base.main_tree_id)
            else set()
        ),
    )


def _components(base: BaseConfig, matching: list[Override], robot: RobotNode) -> dict[str, list[Component]]:
    known = {c.name for kind in KINDS for c in getattr(base, kind)}
    removed: dict[str, str] = {}
    for override in matching:
        for name in override.remove:
            if name not in known:
                raise Unresolved(
                    f"spec.overrides[{override.name}].remove", f"the system has no component {name!r}"
                )
            removed.setdefault(name, override.name)
    added = _Claims()
    for override in matching:
        for kind in KINDS:
            for component in getattr(override.add, kind):
                what = f"add.{kind}[{component.name}]"
                if component.name in known and removed.get(component.name) != override.name:
                    raise Unresolved(
                        f"spec.overrides[{override.name}].{what}",
                        f"the robot already runs a component {component.name!r}; remove it in the same "
                        "override to replace it, or set its image or env",
                    )
                added.claim(override.name, f"add[{component.name}]", (kind, component.to_wire()))
    result: dict[str, list[Component]] = {
        kind: [c for c in getattr(base, kind) if c.name not in removed] for kind in KINDS
    }
    # Sorted, as everything an override adds, so that the overrides' order changes nothing.
    for _, _, (kind, wire) in sorted(added.items(), key=lambda item: item[0]):
        model = ExecutorComponent if kind == "executors" else Component
        result[kind].append(model.model_validate(wire))
    names = {c.name for kind in KINDS for c in result[kind]}
    images, env = _Claims(), _Claims()
    for override in matching:
        for name, image in override.images.items():
            where = f"spec.overrides[{override.name}].images[{name}]"
            if name not in names:
                raise Unresolved(where, f"this robot runs no component {name!r}")
            images.claim(override.name, f"images[{name}]", substitute(image, robot, where))
        for variable in override.env:
            where = f"spec.overrides[{override.name}].env[{variable.name}]"
            env.claim(override.name, f"env[{variable.name}]", substitute(variable.value, robot, where))
    image_of = {what[len("images[") : -1]: (owner, value) for what, owner, value in images.items()}
    variables = sorted((what[len("env[") : -1], owner, value) for what, owner, value in env.items())
    for kind in KINDS:
        result[kind] = [_with(c, image_of.get(c.name), variables) for c in result[kind]]
    return result


def _with(
    component: Component, image: tuple[str, str] | None, variables: list[tuple[str, str, str]]
) -> Component:
    if image is None and not variables:
        return component
    wire = component.to_wire()
    if image is not None:
        wire["image"] = image[1]
    if variables:
        names = {name for name, _, _ in variables}
        kept = [e for e in component.env if e.name not in names]
        wire["env"] = [e.to_wire() for e in kept] + [
            EnvVar(name=n, value=v).to_wire() for n, _, v in variables
        ]
    try:
        return type(component).model_validate(wire)
    except ValidationError as error:
        owner = image[0] if image is not None else variables[0][1]
        detail = "; ".join(f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']}" for e in error.errors())
        raise Unresolved(f"spec.overrides[{owner}]", f"component {component.name}: {detail}") from None


def _leaves(document: Any, path: tuple[str, ...] = ()) -> list[tuple[tuple[str, ...], Any]]:
    if isinstance(document, dict) and document:
        return [leaf for key, value in document.items() for leaf in _leaves(value, (*path, str(key)))]
    return [(path, document)]


def merge(base: Any, update: Any) -> Any:
    """`update` deep-merged onto `base`: mappings key by key, anything else replaced."""
    if isinstance(base, dict) and isinstance(update, dict):
        merged = dict(base)
        for key, value in update.items():
            merged[key] = merge(base[key], value) if key in base else value
        return merged
    return update


class ParsedDocuments:
    """Parameters documents parsed once for every robot they reach (a fleet resolves the same
    override for hundreds of robots); read only, as robots' documents are built anew from them."""

    def __init__(self) -> None:
        self._parsed: dict[tuple[str, str], Any] = {}

    def parse(self, text: str, where: str) -> Any:
        """The mapping `text` holds ({} for none).

        Raises:
            Unresolved: not YAML, or not a mapping; names `where`.
        """
        key = (where, text)
        if key not in self._parsed:
            try:
                document = parsing.load_bounded_yaml(text) or {}
                if not isinstance(document, dict):
                    kind = type(document).__name__
                    document = Unresolved(where, f"parameters must be a mapping of node names, got {kind}")
            except yaml.YAMLError as error:
                document = Unresolved(where, f"invalid YAML: {getattr(error, 'problem', None) or error}")
            self._parsed[key] = document
        if isinstance(self._parsed[key], Unresolved):
            raise self._parsed[key]
        return self._parsed[key]


def _parameters(
    text: str, matching: list[Override], robot: RobotNode, parsed: ParsedDocuments
) -> tuple[str, bool]:
    given = [o for o in matching if o.parameters is not None]
    if not given:
        return text, False
    claims: dict[tuple[str, ...], tuple[str, Any]] = {}
    documents = []
    for override in given:
        where = f"spec.overrides[{override.name}].parameters"
        document = parsed.parse(override.parameters or "", where)
        if not document:
            continue
        document = substitute_values(document, robot, where)
        for path, value in _leaves(document):
            # Equal paths clash on a different value; a leaf of one override inside a leaf of another
            # (a mapping against a scalar) clashes whatever the values.
            for other, (owner, known) in claims.items():
                shorter = min(len(other), len(path))
                if (
                    owner != override.name
                    and other[:shorter] == path[:shorter]
                    and (other != path or known != value)
                ):
                    raise Unresolved(f"{where}.{'.'.join(path)}", CONFLICT.format(other=owner))
            claims.setdefault(path, (override.name, value))
        documents.append(document)
    merged = parsed.parse(text, "spec.parameters")
    for document in documents:
        merged = merge(merged, document)
    return yaml.safe_dump(merged, sort_keys=True, default_flow_style=False, allow_unicode=True), True


def _tree(base: BaseConfig, matching: list[Override]) -> tuple[str, dict[str, str], str | None]:
    claims = _Claims()
    for override in matching:
        if override.tree is None:
            continue
        if override.tree.inline is not None:
            claims.claim(override.name, "tree.inline", override.tree.inline)
        if override.tree.main_tree_id is not None:
            claims.claim(override.name, "tree.mainTreeId", override.tree.main_tree_id)
        for name, text in override.tree.files.items():
            claims.claim(override.name, f"tree.files[{name}]", text)
    tree, files, main_tree_id = base.tree, dict(base.tree_files), base.main_tree_id
    for what, _, value in claims.items():
        if what == "tree.inline":
            tree = value
        elif what == "tree.mainTreeId":
            main_tree_id = value
        else:
            files[what[len("tree.files[") : -1]] = value
    return tree, files, main_tree_id


def _composition_problem(components: Mapping[str, list[Component]]) -> tuple[str, str] | None:
    """The system's own rules over what one robot ends up with (the CRD checks them on the spec)."""
    if not components["executors"]:
        return "spec.overrides", "removes every executor of this robot; at least one is required"
    for kind in ("skillsets", "executors"):
        for component in components[kind]:
            if component.privileged:
                return f"spec.overrides.add.{kind}[{component.name}]", "privileged is allowed only on drivers"
    if groot2_ports_overlap(components["executors"]):  # type: ignore[arg-type]
        return "spec.overrides.add.executors", "executors' groot2 ports must be at least 2 apart"
    return None
