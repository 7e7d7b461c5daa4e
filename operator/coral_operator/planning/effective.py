"""From a revision's template and a robot to the template that robot runs (its effective configuration).

A revision of a system with overrides carries them in its template (`with_overrides`), with the
validated system files they apply to, so any stored revision resolves for any robot without reading
anything: a rollback returns every robot to what that revision gave it. The resolved template has
no overrides left, points at ConfigMaps of its own where an override changed the tree or the
parameters, and carries `configHash`, the hash of all of it. Robots with equal resolutions share one
object, so a fleet of three models costs three resolutions. Pure; used by `planning.system_pass`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from coral_operator.api.components import Component, ExecutorComponent
from coral_operator.api.overrides import Override
from coral_operator.api.system import CoralSystemSpec
from coral_operator.planning import configmaps, naming, selection, validation
from coral_operator.planning.node_values import node_value, references
from coral_operator.planning.observed import RobotNode
from coral_operator.planning.overrides import (
    BaseConfig,
    ConfigError,
    EffectiveConfig,
    ParsedDocuments,
    effective_config,
)

OVERRIDES = "overrides"
"""The template key of a revision's overrides and the system files they apply to."""
CONFIG_HASH = "configHash"


def with_overrides(
    template: dict[str, Any], spec: CoralSystemSpec, tree: str, parameters: str
) -> dict[str, Any]:
    """The revision template of `spec`: `template` as before, plus its overrides when it has any (so
    systems without overrides keep their revision hashes), with only the system files they change:
    the revision must fit in one object."""
    if not spec.overrides:
        return template
    section: dict[str, Any] = {"rules": [o.to_wire() for o in spec.overrides]}
    if any(o.tree is not None for o in spec.overrides):
        section.update(tree=tree, files=dict(spec.tree.files))
    if any(o.parameters is not None for o in spec.overrides):
        section["parameters"] = parameters
    return {**template, OVERRIDES: section}


def validate_changed(
    config: EffectiveConfig, robot: str, label: str, verdicts: validation.Verdicts | None
) -> ConfigError | None:
    """The first problem of the tree or parameters an override changed for `robot`, or None."""
    if "tree" in config.changed:
        problems = validation.validate_tree(
            config.tree,
            f"{label} tree.xml for robot {robot}",
            config.main_tree_id,
            config.tree_files,
            files_label=f"{label} tree files for robot {robot}",
            verdicts=verdicts,
        )
        if problems:
            return ConfigError(
                robot, f"spec.overrides[{', '.join(config.applied)}].tree", validation_summary(problems)
            )
    if "parameters" in config.changed:
        problems = validation.validate_parameters(
            config.parameters, f"{label} parameters for robot {robot}", verdicts
        )
        if problems:
            return ConfigError(
                robot, f"spec.overrides[{', '.join(config.applied)}].parameters", validation_summary(problems)
            )
    return None


def validation_summary(problems: list[str]) -> str:
    more = len(problems) - 3
    return "; ".join(problems[:3]) + (f"; and {more} more" if more > 0 else "")


class EffectiveTemplates:
    """Resolves templates for robots during one system pass; remembers nothing beyond it."""

    def __init__(
        self, *, system: str, namespace: str, system_uid: str, verdicts: validation.Verdicts | None = None
    ) -> None:
        self.system = system
        self.namespace = namespace
        self.system_uid = system_uid
        self.verdicts = verdicts
        self.config_maps: dict[str, dict[str, Any]] = {}
        """The ConfigMaps the resolved templates point at, beyond the revision's own, by name."""
        # Keyed by the template object, which the entry keeps alive so its id is not reused.
        self._plain: dict[int, tuple[dict[str, Any], dict[str, Any]]] = {}
        self._rules: dict[int, tuple[BaseConfig, list[Override], list[set[str]]]] = {}
        self._resolved: dict[tuple[Any, ...], dict[str, Any] | ConfigError] = {}
        self._documents = ParsedDocuments()

    def plain(self, template: dict[str, Any]) -> dict[str, Any]:
        """`template` for a robot no override matches."""
        known = self._plain.get(id(template))
        if known is None:
            base = {k: v for k, v in template.items() if k not in (OVERRIDES, CONFIG_HASH)}
            known = (template, {**base, CONFIG_HASH: naming.content_hash(base)})
            self._plain[id(template)] = known
        return known[1]

    def resolve(self, template: dict[str, Any], robot: RobotNode) -> dict[str, Any] | ConfigError:
        """The template `robot` runs at `template`'s revision, or why it has none."""
        section = template.get(OVERRIDES)
        if not section:
            return self.plain(template)
        base, rules, used = self._parsed(template, section)
        matching = tuple(i for i, rule in enumerate(rules) if selection.matches(rule.robots, robot.labels))
        if not matching:
            return self.plain(template)
        values: list[tuple[str, str | None]] = []
        for i in matching:
            for reference in sorted(used[i]):
                try:
                    values.append((reference, node_value(reference, robot)))
                except ValueError:
                    values.append((reference, None))
        key = (id(template), matching, tuple(values))
        if key not in self._resolved:
            self._resolved[key] = self._build(template, base, rules, robot)
        resolved = self._resolved[key]
        if isinstance(resolved, ConfigError) and resolved.robot != robot.robot:
            return ConfigError(robot.robot, resolved.field, resolved.message)
        return resolved

    def _parsed(
        self, template: dict[str, Any], section: Mapping[str, Any]
    ) -> tuple[BaseConfig, list[Override], list[set[str]]]:
        known = self._rules.get(id(template))
        if known is None:
            rules = [Override.model_validate(rule) for rule in section["rules"]]
            base = BaseConfig(
                tree=section.get("tree", ""),
                tree_files=dict(section.get("files") or {}),
                main_tree_id=(template.get("tree") or {}).get("mainTreeId"),
                parameters=section.get("parameters", ""),
                drivers=[Component.model_validate(c) for c in template.get("drivers") or []],
                skillsets=[Component.model_validate(c) for c in template.get("skillsets") or []],
                executors=[ExecutorComponent.model_validate(c) for c in template.get("executors") or []],
            )
            used = [references(repr(rule.to_wire())) for rule in rules]
            known = (base, rules, used)
            self._rules[id(template)] = known
            self._plain.setdefault(id(template), (template, self.plain(template)))
        return known

    def _build(
        self, template: dict[str, Any], base: BaseConfig, rules: list[Override], robot: RobotNode
    ) -> dict[str, Any] | ConfigError:
        config = effective_config(base, rules, robot, self._documents)
        if isinstance(config, ConfigError):
            return config
        problem = validate_changed(config, robot.robot, f"coralsystem/{self.system}", self.verdicts)
        if problem is not None:
            return problem
        resolved = {k: v for k, v in template.items() if k not in (OVERRIDES, CONFIG_HASH)}
        common = {"system": self.system, "namespace": self.namespace, "system_uid": self.system_uid}
        if "tree" in config.changed:
            tree = dict(resolved["tree"])
            manifest = configmaps.build_config_map(
                **common, kind="tree", key=configmaps.TREE_KEY, text=config.tree, beside=config.tree_files
            )
            self.config_maps[manifest["metadata"]["name"]] = manifest
            tree["configMap"] = manifest["metadata"]["name"]
            tree.pop("mainTreeId", None)
            if config.main_tree_id is not None:
                tree["mainTreeId"] = config.main_tree_id
            resolved["tree"] = tree
        if "parameters" in config.changed:
            manifest = configmaps.build_config_map(
                **common, kind="params", key=configmaps.PARAMS_KEY, text=config.parameters
            )
            self.config_maps[manifest["metadata"]["name"]] = manifest
            resolved["parameters"] = {"configMap": manifest["metadata"]["name"]}
        for kind in ("drivers", "skillsets", "executors"):
            resolved[kind] = [c.to_wire() for c in getattr(config, kind)]
        resolved[CONFIG_HASH] = naming.content_hash(resolved)
        return resolved
