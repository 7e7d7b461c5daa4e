"""Parses a Coral compose file (Docker Compose syntax) into a `Project` the local runtime can run.

What Coral reads from compose (everything else, e.g. `network_mode`, `volumes`, is accepted and
ignored on one machine):

- `name`: project name (default: the folder's name, lowercased without the characters Docker
  Compose refuses in a project name).
- `services.<name>.profiles`: exactly one of `drivers`, `skillsets`, `executors` gives the role.
- `services.<name>.image`: looked up as an installed component (see `coral.local.components`).
- `services.<name>.environment`: mapping or `KEY=VALUE` list. Every value of the file is
  interpolated as Docker Compose does (`${VAR}`, `${VAR:-default}`, `${VAR:?message}`,
  `${VAR:+alt}`, `$$`, ...), from the environment, then `.env` beside the file. Each service's
  whole mapping, interpolated the same way, is kept as `Service.fields` for `coral convert`,
  which maps the fields `coral run` ignores (`command`, `volumes`, `devices`...) onto pods.
- `services.<name>.x-coral`: `command` (argv list or string, run instead of the image's component;
  placeholders `{plugins}`, `{params}`, `{tree}`, `{name}`, `{output}`, `{python}`), `transient`
  (a driver that may exit 0 and count as done), `ready_timeout_s`, `main_tree` / `rate` (executors).
- top-level `x-coral`: `tree` and `params` (paths relative to the file; defaults: the only `*.xml`
  and `params.yaml` beside it), `ready_timeout_s` (default 60), `on_timeout` (`block` or `proceed`),
  `main_tree`, `rate`.

Every problem raises `ComposeError` naming the file and line. Called by `coral.local.running`
and `coral.local.validating`.
"""

from __future__ import annotations

import io
import math
import os
import re
import string
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from coral_core import parsing
from coral_core.limits import MAX_TICK_RATE_HZ
from dotenv.parser import parse_stream

ROLES = {"drivers": "driver", "skillsets": "skillset", "executors": "executor"}
COMPOSE_NAMES = ("compose.yaml", "compose.yml", "docker-compose.yaml", "docker-compose.yml")
# What `coral run` fills into an x-coral.command (coral.local.components.render_command).
COMMAND_PLACEHOLDERS = ("python", "plugins", "params", "tree", "name", "output")
# Docker Compose's rule for project names.
PROJECT_NAME_RE = re.compile(r"^[a-z0-9][a-z0-9_-]*$")
SERVICE_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
SERVICE_EXTENSION_KEYS = {"command", "transient", "ready_timeout_s", "main_tree", "rate", "component"}
TOP_EXTENSION_KEYS = {"tree", "params", "ready_timeout_s", "on_timeout", "main_tree", "rate"}


class ComposeError(ValueError):
    """A compose file Coral cannot run; `str()` reads `file:line: message`."""

    def __init__(self, file: Path, line: int | None, message: str) -> None:
        self.file, self.line, self.message = file, line, message
        super().__init__(f"{file}:{line}: {message}" if line else f"{file}: {message}")


@dataclass
class Service:
    name: str
    role: str  # driver | skillset | executor
    line: int
    image: str | None = None
    command: list[str] | None = None
    component: str | None = None
    environment: dict[str, str] = field(default_factory=dict)
    transient: bool = False
    ready_timeout_s: float | None = None
    main_tree: str | None = None
    rate: float | None = None
    # The service's whole mapping as plain data, every value interpolated (`interpolated_data`).
    fields: dict[str, Any] = field(default_factory=dict)


@dataclass
class Project:
    name: str
    file: Path
    services: list[Service]
    tree: Path | None
    params: Path | None
    ready_timeout_s: float = 60.0
    on_timeout: str = "block"
    main_tree: str | None = None
    rate: float | None = None
    warnings: list[str] = field(default_factory=list)
    # `coral run --groot2-port`: the first executor publishes on this port, the next on port + 2...
    groot2_port: int | None = None
    groot2_allow_hooks: bool = False
    groot2_wait_s: float = 0.0

    @property
    def root(self) -> Path:
        return self.file.parent

    def by_role(self, role: str) -> list[Service]:
        return [s for s in self.services if s.role == role]


def find_compose_file(target: Path) -> Path:
    """`target` itself when it is a file, else the compose file inside the folder."""
    if target.is_file():
        return target
    if not target.is_dir():
        raise ComposeError(target, None, "no such file or folder")
    for name in COMPOSE_NAMES:
        if (target / name).is_file():
            return target / name
    raise ComposeError(target, None, f"no compose file in the folder (looked for {', '.join(COMPOSE_NAMES)})")


def read_dotenv(folder: Path, environ: dict[str, str]) -> dict[str, str]:
    """The `.env` beside the compose file, as Docker Compose reads it: python-dotenv's parser reads
    the syntax (quotes, `export`, comments, multi-line values); values are then interpolated with
    the compose rules against the environment and the lines above, except single-quoted ones,
    which compose takes literally. A line python-dotenv cannot parse is a ComposeError."""
    path = folder / ".env"
    if not path.is_file():
        return {}
    values: dict[str, str] = {}
    text = _read(path)
    for binding in parse_stream(io.StringIO(text)):
        if binding.error:
            raise ComposeError(path, binding.original.line, f"cannot parse {binding.original.string!r}")
        if binding.key is None or binding.value is None:
            continue
        literal = binding.original.string.partition("=")[2].lstrip().startswith("'")
        values[binding.key] = (
            binding.value
            if literal
            else interpolate(binding.value, {**values, **environ}, path, binding.original.line)
        )
    return values


# Hand-written on purpose: python-dotenv only knows `${VAR:-default}`, and no maintained Python
# library implements the compose-spec grammar (`:?`/`?` errors, `:+`/`+`, nested defaults, `$$`).
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_OPERATORS = (":-", ":?", ":+", "-", "?", "+")


def interpolate(text: str, env: dict[str, str], file: Path, line: int) -> str:
    """Variable substitution as the compose specification defines it (interpolation.md).

    `$VAR` and `${VAR}` (unset: empty), `${VAR:-default}` / `${VAR-default}` (unset or empty /
    unset), `${VAR:?message}` / `${VAR?message}` (raise ComposeError), `${VAR:+alt}` / `${VAR+alt}`
    (alt when set and non-empty / set), `$$` for a literal `$`; defaults, messages and alternatives
    may themselves hold variables, expanded only when used.
    """
    out: list[str] = []
    index = 0
    while index < len(text):
        dollar = text.find("$", index)
        if dollar < 0:
            out.append(text[index:])
            break
        out.append(text[index:dollar])
        following = text[dollar + 1 : dollar + 2]
        if following == "$":
            out.append("$")
            index = dollar + 2
        elif following == "{":
            end = _closing_brace(text, dollar + 2)
            if end < 0:
                raise ComposeError(file, line, f"invalid interpolation format in {text!r}: missing '}}'")
            out.append(_braced(text[dollar + 2 : end], text, env, file, line))
            index = end + 1
        elif match := _NAME.match(text, dollar + 1):
            out.append(env.get(match.group(), ""))
            index = match.end()
        else:
            raise ComposeError(
                file, line, f"invalid interpolation format in {text!r}: write $$ for a literal '$'"
            )
    return "".join(out)


def _closing_brace(text: str, start: int) -> int:
    """Index of the `}` closing a `${` whose body starts at `start` (nested `${...}` skipped), or -1."""
    depth = 1
    index = start
    while index < len(text):
        if text.startswith("$$", index):
            index += 2
            continue
        if text.startswith("${", index):
            depth += 1
            index += 2
            continue
        if text[index] == "}":
            depth -= 1
            if depth == 0:
                return index
        index += 1
    return -1


def _braced(body: str, text: str, env: dict[str, str], file: Path, line: int) -> str:
    match = _NAME.match(body)
    operator = next((op for op in _OPERATORS if match and body.startswith(op, match.end())), None)
    if match is None or (operator is None and match.end() != len(body)):
        raise ComposeError(file, line, f"invalid interpolation format in {text!r}: ${{{body}}}")
    name = match.group()
    value = env.get(name)
    if operator is None:
        return value or ""
    argument = body[match.end() + len(operator) :]
    missing = value is None or (operator.startswith(":") and value == "")
    if operator.endswith("-"):
        return interpolate(argument, env, file, line) if missing else str(value)
    if operator.endswith("?"):
        if missing:
            message = interpolate(argument, env, file, line) or ("not set" if value is None else "empty")
            raise ComposeError(file, line, f"variable {name} is required: {message}")
        return str(value)
    return "" if missing else interpolate(argument, env, file, line)


def _line(node: yaml.Node) -> int:
    return node.start_mark.line + 1


_RESOLVER = yaml.resolver.Resolver()
_STRING_TAG = "tag:yaml.org,2002:str"
# What an unquoted value may become once interpolated, as Docker Compose casts `privileged:
# ${PRIVILEGED}` to a boolean; an empty result stays an empty string, as in compose.
_CAST_TAGS = {"tag:yaml.org,2002:bool", "tag:yaml.org,2002:int", "tag:yaml.org,2002:float"}


def _interpolated_node(
    node: yaml.Node, file: Path, env: dict[str, str], done: dict[int, yaml.Node]
) -> yaml.Node:
    """A copy of `node` with every string value interpolated; keys are left as written, as compose
    leaves them. `done` maps nodes already copied, so an alias stays one shared (even recursive) node."""
    if id(node) in done:
        return done[id(node)]
    if isinstance(node, yaml.ScalarNode):
        if node.tag != _STRING_TAG or "$" not in node.value:
            return node
        value = interpolate(node.value, env, file, _line(node))
        tag = _RESOLVER.resolve(yaml.ScalarNode, value, (True, False)) if node.style is None else node.tag
        return yaml.ScalarNode(
            tag if tag in _CAST_TAGS else _STRING_TAG, value, node.start_mark, node.end_mark, node.style
        )
    copy: yaml.CollectionNode
    if isinstance(node, yaml.SequenceNode):
        copy = done[id(node)] = yaml.SequenceNode(
            node.tag, [], node.start_mark, node.end_mark, node.flow_style
        )
        copy.value.extend(_interpolated_node(item, file, env, done) for item in node.value)
    else:
        copy = done[id(node)] = yaml.MappingNode(
            node.tag, [], node.start_mark, node.end_mark, node.flow_style
        )
        copy.value.extend((key, _interpolated_node(value, file, env, done)) for key, value in node.value)
    return copy


def interpolated_data(node: yaml.Node, file: Path, env: dict[str, str]) -> Any:
    """The YAML `node` as plain data (merge keys applied), every value interpolated as compose does.

    Raises ComposeError naming the line of a value that does not interpolate or a mapping YAML
    cannot build."""
    try:
        return yaml.constructor.SafeConstructor().construct_document(_interpolated_node(node, file, env, {}))
    except yaml.constructor.ConstructorError as err:
        mark = err.problem_mark or err.context_mark
        raise ComposeError(file, mark.line + 1 if mark else None, str(err.problem)) from None


def _mapping(node: yaml.Node, file: Path, what: str) -> dict[str, tuple[yaml.Node, yaml.Node]]:
    if not isinstance(node, yaml.MappingNode):
        raise ComposeError(file, _line(node), f"{what} must be a mapping")
    return {str(k.value): (k, v) for k, v in node.value}


def _scalar(node: yaml.Node, file: Path, what: str, env: dict[str, str]) -> str:
    if not isinstance(node, yaml.ScalarNode):
        raise ComposeError(file, _line(node), f"{what} must be a single value")
    return interpolate(str(node.value), env, file, _line(node))


def _check_placeholders(command: list[str], file: Path, line: int, service: str) -> None:
    """Every `{placeholder}` of an x-coral.command must be one `coral run` fills in."""
    for part in command:
        try:
            names = [name for _, name, _, _ in string.Formatter().parse(part) if name is not None]
        except ValueError as err:
            raise ComposeError(file, line, f"service {service}: x-coral.command {part!r}: {err}") from None
        for name in names:
            if name not in COMMAND_PLACEHOLDERS:
                raise ComposeError(
                    file,
                    line,
                    f"service {service}: x-coral.command has placeholder {{{name}}}; known: "
                    + ", ".join(f"{{{known}}}" for known in COMMAND_PLACEHOLDERS)
                    + " (write {{ and }} for braces)",
                )


def _read(file: Path) -> str:
    try:
        return parsing.read_text(file)
    except OSError as err:
        raise ComposeError(file, None, f"cannot read: {err.strerror}") from err
    except parsing.NotText as err:
        raise ComposeError(file, err.line, err.reason) from err


def _project_name(node: yaml.Node, file: Path, env: dict[str, str]) -> str:
    name = _scalar(node, file, "name", env)
    if not PROJECT_NAME_RE.match(name):
        raise ComposeError(
            file,
            _line(node),
            f"name {name!r} must hold only lowercase letters, digits, dashes and underscores, and start "
            "with a letter or digit (as Docker Compose requires): it names the run's folders",
        )
    return name


def _folder_project_name(file: Path) -> str:
    """The folder's name made a project name as Docker Compose does: lowercased, without the
    characters a name cannot hold, and without leading dashes and underscores."""
    name = re.sub(r"[^a-z0-9_-]", "", file.parent.name.lower()).lstrip("_-")
    if not name:
        raise ComposeError(
            file, None, f"the folder name {file.parent.name!r} gives no project name; set a top-level name"
        )
    return name


def _positive_number(
    node: yaml.Node, file: Path, what: str, env: dict[str, str], at_most: float = math.inf
) -> float:
    text = _scalar(node, file, what, env)
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    # Both of Coral's numbers are a duration or a rate: zero, negative or infinite would mean a
    # timeout that fires at once or never, or a tree that never ticks.
    if not (math.isfinite(value) and 0 < value <= at_most):
        bound = "" if math.isinf(at_most) else f" up to {at_most:g}"
        raise ComposeError(file, _line(node), f"{what} must be a positive number{bound}, not {text!r}")
    return value


def _tick_rate(node: yaml.Node, file: Path, env: dict[str, str]) -> float:
    # The executor's limit, and a CoralSystem's (tree.tickRateHz).
    return _positive_number(node, file, "rate", env, at_most=MAX_TICK_RATE_HZ)


def _boolean(node: yaml.Node, file: Path, what: str, env: dict[str, str]) -> bool:
    text = _scalar(node, file, what, env).lower()
    if text in ("true", "yes", "on", "1"):
        return True
    if text in ("false", "no", "off", "0"):
        return False
    raise ComposeError(file, _line(node), f"{what} must be true or false, not {text!r}")


def _strings(node: yaml.Node, file: Path, what: str, env: dict[str, str]) -> list[str]:
    if isinstance(node, yaml.ScalarNode):
        return [interpolate(str(node.value), env, file, _line(node))]
    if not isinstance(node, yaml.SequenceNode):
        raise ComposeError(file, _line(node), f"{what} must be a list")
    return [_scalar(item, file, what, env) for item in node.value]


def _environment(node: yaml.Node, file: Path, env: dict[str, str]) -> dict[str, str]:
    values: dict[str, str] = {}
    if isinstance(node, yaml.SequenceNode):
        for item in node.value:
            key, sep, value = _scalar(item, file, "environment entry", env).partition("=")
            values[key] = value if sep else env.get(key, "")
        return values
    for key, (_, value_node) in _mapping(node, file, "environment").items():
        values[key] = "" if value_node.tag.endswith(":null") else _scalar(value_node, file, key, env)
    return values


def _service(name: str, key: yaml.Node, node: yaml.Node, file: Path, env: dict[str, str]) -> Service:
    if not SERVICE_NAME_RE.match(name):
        raise ComposeError(
            file,
            _line(key),
            f"service name {name!r} must match {SERVICE_NAME_RE.pattern} "
            "(it becomes the component's ROS node name)",
        )
    fields = _mapping(node, file, f"service {name}")
    profiles = _strings(fields["profiles"][1], file, "profiles", env) if "profiles" in fields else []
    roles = sorted({ROLES[p] for p in profiles if p in ROLES})
    if len(roles) != 1:
        raise ComposeError(
            file,
            _line(fields["profiles"][0] if "profiles" in fields else key),
            f"service {name} needs exactly one of the profiles {', '.join(ROLES)}"
            f" (found {profiles or 'none'})",
        )
    service = Service(name=name, role=roles[0], line=_line(key), fields=interpolated_data(node, file, env))
    if "image" in fields:
        service.image = _scalar(fields["image"][1], file, "image", env)
    if "environment" in fields:
        service.environment = _environment(fields["environment"][1], file, env)
    if "x-coral" in fields:
        extension = _mapping(fields["x-coral"][1], file, f"service {name} x-coral")
        for option, (option_key, _value) in extension.items():
            if option not in SERVICE_EXTENSION_KEYS:
                raise ComposeError(
                    file,
                    _line(option_key),
                    f"unknown x-coral option {option!r} in service {name} "
                    f"(known: {', '.join(sorted(SERVICE_EXTENSION_KEYS))})",
                )
        if "command" in extension:
            node_ = extension["command"][1]
            service.command = (
                _scalar(node_, file, "command", env).split()
                if isinstance(node_, yaml.ScalarNode)
                else _strings(node_, file, "command", env)
            )
            _check_placeholders(service.command, file, _line(node_), name)
        if "component" in extension:
            service.component = _scalar(extension["component"][1], file, "component", env)
        if "transient" in extension:
            service.transient = _boolean(extension["transient"][1], file, "transient", env)
            if service.transient and service.role != "driver":
                raise ComposeError(file, _line(extension["transient"][0]), "only drivers can be transient")
        if "ready_timeout_s" in extension:
            timeout_node = extension["ready_timeout_s"][1]
            service.ready_timeout_s = _positive_number(timeout_node, file, "ready_timeout_s", env)
        if "main_tree" in extension:
            service.main_tree = _scalar(extension["main_tree"][1], file, "main_tree", env)
        if "rate" in extension:
            service.rate = _tick_rate(extension["rate"][1], file, env)
    if service.image is None and service.command is None and service.role != "executor":
        raise ComposeError(file, service.line, f"service {name} needs an image or an x-coral command")
    return service


_REQUIRED = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*):?\?")


def _placeholders_for_required(
    text: str, env: dict[str, str], file: Path
) -> tuple[dict[str, str], list[str]]:
    """Values standing in for unset required variables, and a warning (file:line) for each."""
    values: dict[str, str] = {}
    warnings: list[str] = []
    for number, line in enumerate(text.splitlines(), start=1):
        for name in _REQUIRED.findall(line):
            if not env.get(name) and name not in values:
                values[name] = f"<{name}>"
                warnings.append(
                    f"{file}:{number}: variable {name} is not set (required when the project runs)"
                )
    return values, warnings


def parse_compose(file: Path, environ: dict[str, str] | None = None, *, lenient: bool = False) -> Project:
    """Reads and checks a compose file; raises ComposeError (file:line) on the first problem.

    `lenient` (for validation) lets unset required variables pass as placeholders, with warnings.
    """
    file = Path(file).resolve()
    text = _read(file)
    environ = dict(os.environ if environ is None else environ)
    env = {**read_dotenv(file.parent, environ), **environ}
    warnings: list[str] = []
    if lenient:
        placeholders, warnings = _placeholders_for_required(text, env, file)
        env.update(placeholders)
    try:
        root = parsing.compose_yaml(text)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        raise ComposeError(
            file, mark.line + 1 if mark else None, f"invalid YAML: {getattr(err, 'problem', err)}"
        ) from err
    if root is None:
        raise ComposeError(file, None, "the file is empty")
    top = _mapping(root, file, "a compose file")
    if "services" not in top:
        raise ComposeError(file, 1, "no 'services' section")
    services = [
        _service(name, key, node, file, env)
        for name, (key, node) in _mapping(top["services"][1], file, "services").items()
    ]
    project = Project(
        name=_project_name(top["name"][1], file, env) if "name" in top else _folder_project_name(file),
        file=file,
        services=services,
        tree=None,
        params=None,
        warnings=warnings,
    )
    extension = _mapping(top["x-coral"][1], file, "x-coral") if "x-coral" in top else {}
    for option, (option_key, _) in extension.items():
        if option not in TOP_EXTENSION_KEYS:
            raise ComposeError(
                file,
                _line(option_key),
                f"unknown x-coral option {option!r} (known: {', '.join(sorted(TOP_EXTENSION_KEYS))})",
            )
    if "tree" in extension:
        project.tree = file.parent / _scalar(extension["tree"][1], file, "tree", env)
    else:
        trees = sorted(file.parent.glob("*.xml"))
        project.tree = trees[0] if len(trees) == 1 else None
    if "params" in extension:
        project.params = file.parent / _scalar(extension["params"][1], file, "params", env)
    elif (file.parent / "params.yaml").is_file():
        project.params = file.parent / "params.yaml"
    if "ready_timeout_s" in extension:
        timeout_node = extension["ready_timeout_s"][1]
        project.ready_timeout_s = _positive_number(timeout_node, file, "ready_timeout_s", env)
    if "on_timeout" in extension:
        project.on_timeout = _scalar(extension["on_timeout"][1], file, "on_timeout", env).lower()
        if project.on_timeout not in ("block", "proceed"):
            raise ComposeError(file, _line(extension["on_timeout"][0]), "on_timeout must be block or proceed")
    if "main_tree" in extension:
        project.main_tree = _scalar(extension["main_tree"][1], file, "main_tree", env)
    if "rate" in extension:
        project.rate = _tick_rate(extension["rate"][1], file, env)
    if project.by_role("executor") and project.tree is None:
        raise ComposeError(
            file, None, "executors need a tree: set x-coral.tree or keep exactly one *.xml beside the file"
        )
    for path, what in ((project.tree, "tree"), (project.params, "params")):
        if path is not None and not path.is_file():
            line = _line(extension[what][0]) if what in extension else None
            raise ComposeError(file, line, f"{what} file {path} does not exist")
    return project


def line_of_service(project: Project, name: str) -> int:
    return next((s.line for s in project.services if s.name == name), 0)


def as_dict(project: Project) -> dict[str, Any]:
    return {
        "name": project.name,
        "file": str(project.file),
        "tree": str(project.tree) if project.tree else None,
        "params": str(project.params) if project.params else None,
        "services": [
            {"name": s.name, "role": s.role, "image": s.image, "transient": s.transient}
            for s in project.services
        ],
    }
