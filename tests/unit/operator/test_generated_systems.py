"""Generated CoralSystems, hostile and odd, thrown at the pure validation and planning functions.

Property: they never raise; every refusal names the field (or the file and line) it is about. The
policy is generated too (issue 47: administrators' host-path folders per namespace), and every pod
built mounts a host path only from a folder the namespace may mount, the rest as a relative subPath.
"""

from __future__ import annotations

import re
from typing import Any

from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import CoralSystemSpec
from coral_operator.planning import instances, pods, policy, validation
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from operator_specs import robot
from pydantic import ValidationError

NODES = [
    "Sequence",
    "Fallback",
    "Inverter",
    "Repeat",
    "Sleep",
    "Script",
    "SubTree",
    "AlwaysSuccess",
    "Plugin",
]
PORTS = ["num_cycles", "msec", "code", "ID", "name", "if", "x"]
PATHS = st.one_of(
    st.sampled_from(
        [
            "/",
            "/dev/mem",
            "/dev/ttyUSB0",
            "/var/lib/coral/plugins",
            "/var/lib/coral/../../etc",
            "//etc",
            "/var/lib/coral/data/ns",
            "/var/lib/coral/data/ns/maps/",
            "/var/lib/coral/data/ns/../other/x",
            "/var/lib/coral/data/other",
            "/srv/maps/a",
        ]
    ),
    st.text(alphabet="/.abc", max_size=20).map(lambda text: "/" + text),
    st.text(max_size=5),
)
POLICY_HOST_PATHS = st.lists(
    st.tuples(st.sampled_from(["ns", "other", "*"]), PATHS.filter(lambda path: path.startswith("/"))),
    max_size=3,
)
LABEL_KEYS = st.sampled_from(["fleet", "coral.dev/model", "fleet", "bad key", ""])
LABEL_VALUES = st.sampled_from(["a", "b", "x-1", "a", "bad value!"])
# Messages of the model-level rules, each of which names its field in words.
FIELD_WORDS = (
    "robots",
    "privileged",
    "names",
    "executor",
    "domainId",
    "inline",
    "operator",
    "files",
    "maxUnavailable",
)


def _element(children: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
    attrs = st.dictionaries(st.sampled_from(PORTS), st.text(alphabet="ab1{}<&'-", max_size=6), max_size=3)

    def render(tag: str, attributes: dict[str, str], inner: list[str]) -> str:
        text = "".join(f' {k}="{v.replace(chr(34), "")}"' for k, v in attributes.items())
        return f"<{tag}{text}>{''.join(inner)}</{tag}>"

    return st.builds(render, st.sampled_from(NODES), attrs, st.lists(children, max_size=3))


TREES = st.recursive(st.sampled_from(["<AlwaysSuccess/>", "<Sleep/>", ""]), _element, max_leaves=12)


def _document(body: str, depth: int, include: str | None) -> str:
    deep = "<Inverter>" * depth + body + "</Inverter>" * depth
    included = f'<include path="{include}"/>' if include is not None else ""
    return f'<root BTCPP_format="4">{included}<BehaviorTree ID="Main">{deep}</BehaviorTree></root>'


TREE_TEXT = st.one_of(
    st.builds(_document, TREES, st.integers(0, 400), st.none() | PATHS | st.just("nav.xml")),
    st.text(max_size=200),
)
COMPONENT = st.fixed_dictionaries(
    {"name": st.sampled_from(["a", "b", "lidar", "Bad_Name", ""]), "image": st.sampled_from(["img:1", ""])},
    optional={
        "privileged": st.booleans(),
        "runAsRoot": st.booleans(),
        "devices": st.lists(st.fixed_dictionaries({"hostPath": PATHS}), max_size=2),
        "hostPaths": st.lists(st.fixed_dictionaries({"hostPath": PATHS, "mountPath": PATHS}), max_size=2),
        "resources": st.fixed_dictionaries(
            {
                "limits": st.dictionaries(
                    st.sampled_from(["cpu", "memory"]), st.integers(-2, 5) | st.text(max_size=5)
                )
            }
        ),
    },
)
SPECS = st.fixed_dictionaries(
    {
        "robots": st.fixed_dictionaries(
            {},
            optional={
                "matchLabels": st.dictionaries(LABEL_KEYS, LABEL_VALUES, max_size=2),
                "matchExpressions": st.lists(
                    st.fixed_dictionaries(
                        {
                            "key": LABEL_KEYS,
                            "operator": st.sampled_from(["In", "NotIn", "Exists", "DoesNotExist", "Near"]),
                            "values": st.lists(LABEL_VALUES, max_size=2),
                        }
                    ),
                    max_size=2,
                ),
            },
        ),
        "parameters": st.fixed_dictionaries({"inline": st.text(max_size=40)}),
        "tree": st.fixed_dictionaries(
            {"inline": TREE_TEXT},
            optional={
                "files": st.dictionaries(
                    st.sampled_from(["nav.xml", "nav.xml", "more.xml", "tree.xml", "a b"]),
                    TREE_TEXT,
                    max_size=2,
                )
            },
        ),
        "executors": st.lists(COMPONENT, max_size=2),
    },
    optional={
        "drivers": st.lists(COMPONENT, max_size=2),
        "plugins": st.fixed_dictionaries({"hostPathRoot": PATHS}),
        "ros": st.fixed_dictionaries({"network": st.sampled_from(["Host", "Pod", "Mesh"])}),
        "rollout": st.fixed_dictionaries(
            {"maxUnavailable": st.integers(-3, 50) | st.sampled_from(["10%", "100%", "lots", "3"])}
        ),
    },
)


def _named(kind: str, components: list[dict[str, Any]], keep: bool) -> list[dict[str, Any]]:
    # Most examples get unique, valid names so that they reach validation and planning.
    return components if keep else [{**c, "name": f"{kind}{i}"} for i, c in enumerate(components)]


@st.composite
def systems(draw: st.DrawFn) -> dict[str, Any]:
    raw = draw(SPECS)
    wild = draw(st.integers(0, 9)) == 0
    if not wild:
        raw["robots"] = raw["robots"] or {"matchLabels": {"fleet": "a"}}
        raw["executors"] = _named("executor", raw["executors"] or [{"name": "x", "image": "img:1"}], False)
        raw["drivers"] = _named("driver", raw.get("drivers", []), False)
    return raw


@settings(
    max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large]
)
@given(raw=systems(), opened=POLICY_HOST_PATHS)
def test_generated_systems_are_refused_by_field_or_planned_never_crash(
    raw: dict[str, Any], opened: list[tuple[str, str]]
) -> None:
    try:
        spec = CoralSystemSpec.model_validate(raw)
    except ValidationError as error:
        for item in error.errors():
            assert item["loc"] or any(word in item["msg"] for word in FIELD_WORDS), item
        return
    assert spec.tree.inline is not None and spec.parameters.inline is not None
    problems = validation.validate_tree(spec.tree.inline, "spec.tree.inline", None, spec.tree.files)
    problems += validation.validate_parameters(spec.parameters.inline, "spec.parameters.inline")
    assert all(problem.startswith("spec.") for problem in problems), problems
    rules = policy.Policy(host_paths=tuple((ns, policy.normalise(folder)) for ns, folder in opened))
    refusals = policy.evaluate_policy("ns", spec, rules)
    assert all(refusal.startswith("spec.") for refusal in refusals), refusals
    template = instances.build_template(spec, "tree-cm", "params-cm")
    instance = CoralInstanceSpec.model_validate(instances.build_instance_spec("sys", robot("r1"), template))
    try:
        built = pods.build_pods(
            spec=instance,
            instance="sys-r1",
            namespace="ns",
            instance_uid="u",
            settings=pods.PodSettings(policy=rules),
        )
    except pods.HostPathRefused:
        assert any("hostPaths" in refusal for refusal in refusals), refusals
        return
    assert len(built) == len(spec.drivers) + len(spec.skillsets) + len(spec.executors)
    allowed = policy.allowed_folders(rules, "ns")
    for pod in built:
        for volume in pod["spec"]["volumes"]:
            if volume["name"].startswith("host-"):
                assert volume["hostPath"]["path"] in allowed, volume
        for container in [*pod["spec"].get("initContainers", []), *pod["spec"]["containers"]]:
            if container["name"] == pods.FOLDERS_OWNER:
                assert container["image"] == pods.DEFAULT_HELPER_IMAGE, container
            for mount in container["volumeMounts"]:
                sub_path = mount.get("subPath", "")
                assert not sub_path.startswith("/") and ".." not in sub_path.split("/"), mount


SUBDOMAIN = re.compile(r"[a-z0-9]([-a-z0-9]*[a-z0-9])?(\.[a-z0-9]([-a-z0-9]*[a-z0-9])?)*")


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    part=st.sampled_from(["tree", "parameters"]),
    name=st.text(alphabet="ab0-.%/ A_", min_size=1, max_size=12),
    key=st.text(alphabet="ab0-._/%", min_size=1, max_size=8),
)
def test_generated_config_map_references_are_admitted_only_as_the_api_server_names_them(
    spec_dict: Any, part: str, name: str, key: str
) -> None:
    """Issue 47, item 9: a name with `%` passed admission and then got a 400 on every read."""
    raw = spec_dict(**{part: {"configMapRef": {"name": name, "key": key}}})
    try:
        CoralSystemSpec.model_validate(raw)
    except ValidationError as error:
        locations = {".".join(str(p) for p in item["loc"]) for item in error.errors()}
        assert locations <= {f"{part}.configMapRef.name", f"{part}.configMapRef.key"}, locations
        assert not (SUBDOMAIN.fullmatch(name) and re.fullmatch(r"[-._a-zA-Z0-9]+", key))
        return
    assert SUBDOMAIN.fullmatch(name) and re.fullmatch(r"[-._a-zA-Z0-9]+", key)
