"""The images built from the repository's Dockerfiles are in the registry and really run.

Built once per machine through the content cache (`built_images`); each check runs a command in a
fresh working container of the image with buildah, as the image's own user. Images are named by
ID, so another checkout building on the same machine (and moving the tags) cannot swap them.
"""

from __future__ import annotations

import shlex

import pytest
from coral.local import checking
from coral_core import image_exports, image_labels
from coral_testbed import images
from coral_testbed.images import building, catalog, registry

pytestmark = [pytest.mark.slow, pytest.mark.timeout(3600)]

CORAL_UID = "10001"
SKILLSET_PLUGIN = {"examples-skillset": "examples", "slam-skillset": "slam"}
TREE = (
    '<root BTCPP_format="4" main_tree_to_execute="Main"><BehaviorTree ID="Main">'
    "<Sequence><AlwaysSuccess/><AlwaysSuccess/></Sequence></BehaviorTree></root>"
)


def _entrypoint(built: images.Built) -> list[str]:
    return list(images.builder().config(built.image_id).get("Entrypoint") or [])


def _run(built: images.Built, script: str) -> str:
    done = images.builder().run(built.image_id, ["sh", "-c", script])
    output = f"{done.stdout}{done.stderr}"
    assert done.returncode == 0, f"{built.spec.name}: `{script}` exited {done.returncode}:\n{output}"
    return done.stdout


def test_every_image_is_in_the_registry_under_its_name(
    built_images: dict[str, images.Built], image_registry: str
) -> None:
    for spec in catalog.IMAGES:
        found = registry.manifest(image_registry, spec.repository, spec.tag)
        assert found is not None, f"{spec.reference} is not in the registry at {image_registry}"
        assert found.config_digest == f"sha256:{built_images[spec.name].image_id}", spec.reference


def test_component_images_run_as_coral_and_share_the_runtime_layers(
    built_images: dict[str, images.Built], image_registry: str
) -> None:
    runtime = registry.manifest(image_registry, "coral/runtime", catalog.VERSION)
    assert runtime is not None
    for name in catalog.COMPONENTS:
        spec = built_images[name].spec
        config = images.builder().config(built_images[name].image_id)
        # Numeric: kubelets refuse `runAsNonRoot` pods whose image names its user.
        assert config.get("User") == f"{CORAL_UID}:{CORAL_UID}", f"{name} runs as {config.get('User')!r}"
        assert config.get("Entrypoint", [])[:2] == ["python", "-m"], f"{name}: {config.get('Entrypoint')}"
        found = registry.manifest(image_registry, spec.repository, spec.tag)
        assert found is not None
        assert found.layers[: len(runtime.layers)] == runtime.layers, f"{name} does not start from runtime"
        extra = sum(size for _, size in found.layers[len(runtime.layers) :])
        assert extra < 1024, f"{name} adds {extra} bytes of layers on top of the runtime"
    assert _run(built_images["runtime"], "id -un; id -u; id -g").split() == ["coral", CORAL_UID, CORAL_UID]


def test_the_runtime_loads_ros_and_creates_a_node(built_images: dict[str, images.Built]) -> None:
    script = (
        "python -c 'import coral, coral_skillsets, coral_drivers, rclpy\n"
        "rclpy.init()\n"
        "node = rclpy.create_node(\"image_probe\")\n"
        "print(node.get_fully_qualified_name())\n"
        "node.destroy_node()\n"
        "rclpy.shutdown()'"
    )
    assert _run(built_images["runtime"], script).strip() == "/image_probe"


@pytest.mark.parametrize("name", catalog.COMPONENTS)
def test_each_component_entrypoint_answers_help(built_images: dict[str, images.Built], name: str) -> None:
    entrypoint = _entrypoint(built_images[name])
    output = _run(built_images[name], shlex.join([*entrypoint, "--help"]))
    assert output.startswith("Usage:"), output


def test_the_executor_image_runs_a_tree_to_success(built_images: dict[str, images.Built]) -> None:
    entrypoint = shlex.join(_entrypoint(built_images["executor"]))
    script = (
        f"printf '%s' {shlex.quote(TREE)} > /tmp/tree.xml && {entrypoint} --tree /tmp/tree.xml"
        " && tail -n 1 /var/lib/coral/status/status.jsonl"
    )
    output = _run(built_images["executor"], script)
    assert '"event": "finished", "exit_code": 0, "root_status": "SUCCESS"' in output.splitlines()[-1], output


def test_the_bag_player_image_plays_a_bag_to_its_end(built_images: dict[str, images.Built]) -> None:
    entrypoint = shlex.join(_entrypoint(built_images["bag-player"]))
    params = "bag_player:\n  ros__parameters:\n    rate: 0.0\n    wait_for_subscribers: 0\n"
    script = (
        "coral generate-bag --scans 3 --columns 64 --beams 2 --output /tmp/dataset > /dev/null"
        f" && printf {shlex.quote(params)} > /tmp/params.yaml"
        f" && CORAL_BAG=/tmp/dataset/bag {entrypoint} --params /tmp/params.yaml 2>&1; echo exit=$?"
    )
    output = _run(built_images["bag-player"], script)
    assert "Played 6 message(s)" in output and output.rstrip().endswith("exit=0"), output


@pytest.mark.parametrize("name", sorted(SKILLSET_PLUGIN))
def test_skillset_images_export_their_plugin_and_stop_cleanly(
    built_images: dict[str, images.Built], name: str
) -> None:
    entrypoint = shlex.join(_entrypoint(built_images[name]))
    ready = f"/var/lib/coral/plugins/{SKILLSET_PLUGIN[name]}/ready"
    # The skillset serves until SIGINT; the loop is the deadline for its export, inside the container.
    script = (
        f"{entrypoint} & pid=$!; "
        f"for i in $(seq 600); do [ -e {ready} ] && break; kill -0 $pid || break; sleep 0.1; done; "
        f"test -e {ready} && echo exported; kill -INT $pid; wait $pid; echo exit=$?"
    )
    output = _run(built_images[name], script)
    assert "exported" in output and "exit=0" in output, output


@pytest.mark.parametrize("name", catalog.EXPORTING)
def test_component_images_declare_what_their_component_exports_to_preflight(
    built_images: dict[str, images.Built], image_registry: str, name: str
) -> None:
    """The label preflight reads from the registry by digest is the component's own manifest."""
    spec = built_images[name].spec
    digest, labels = image_labels.ImageLabels().labels(f"{image_registry}/{spec.reference}")
    assert digest == built_images[name].digest
    declared = image_exports.from_labels(labels, spec.reference)
    manifest = checking.verify_component(spec.repository).manifest
    assert manifest is not None and declared == manifest.image_exports()  # type: ignore[attr-defined]


def test_the_operator_image_runs_coral(built_images: dict[str, images.Built]) -> None:
    operator = built_images["operator"]
    config = images.builder().config(operator.image_id)
    assert config.get("Entrypoint") == ["coral"] and config.get("Cmd") == ["operator"]
    output = _run(operator, "coral operator --help")
    assert "Usage:" in output, output
    user = config.get("User", "")
    assert user.split(":")[0].isdigit() and user.split(":")[0] != "0", f"operator runs as {user!r}"


# What each side's image must not hold (issue 52): the operator no robot runtime or ROS, the
# components no operator; neither the testbed.
ROBOT_SIDE = {"coral", "coral_skillsets", "coral_drivers", "rclpy", "rosbags", "kiss_icp"}
OPERATOR_SIDE = {"coral_operator"}
# Every top-level module and package the image's Python can import, one a line.
LIST_PACKAGES = "python -c 'import pkgutil; [print(m.name) for m in pkgutil.iter_modules()]'"


@pytest.mark.parametrize(
    ("name", "holds", "holds_not", "verbs"),
    [
        (
            "operator",
            {"coral_core", "coral_operator"},
            ROBOT_SIDE | {"coral_testbed"},
            {"operator", "convert", "crds", "rollout"},
        ),
        (
            "runtime",
            {"coral_core", "coral", "coral_skillsets", "coral_drivers", "rclpy"},
            OPERATOR_SIDE | {"coral_testbed"},
            {"run", "executor", "skillset", "generate-bag"},
        ),
    ],
)
def test_each_image_holds_its_own_side_and_offers_its_verbs(
    built_images: dict[str, images.Built], name: str, holds: set[str], holds_not: set[str], verbs: set[str]
) -> None:
    """Every component image starts from the runtime's layers and adds none of Python
    (`test_component_images_run_as_coral_and_share_the_runtime_layers`), so the runtime speaks for them."""
    packages = set(_run(built_images[name], LIST_PACKAGES).split())
    assert holds <= packages, f"{name} lacks {sorted(holds - packages)}"
    assert not holds_not & packages, f"{name} holds {sorted(holds_not & packages)}"
    listed = _run(built_images[name], "coral --help").split("Commands:")[1]
    offered = {line.split()[0] for line in listed.splitlines() if line.strip()}
    assert verbs <= offered, f"{name} offers {sorted(offered)}"
    assert not {"dev-cluster", "images", "demo"} & offered, f"{name} offers the testbed's verbs"
    other = {"operator", "crds"} if name == "runtime" else {"run", "executor"}
    assert not other & offered, f"{name} offers the other side's verbs: {sorted(other & offered)}"


def test_an_unchanged_tree_rebuilds_nothing(
    built_images: dict[str, images.Built], image_registry: str
) -> None:
    again = images.build(registry_address=image_registry, progress=lambda line: None)
    assert {name: b.outcome for name, b in again.items()} == {name: "cached" for name in built_images}
    assert {name: b.image_id for name, b in again.items()} == {
        name: b.image_id for name, b in built_images.items()
    }


def test_images_the_local_store_lost_come_back_from_the_registry(
    built_images: dict[str, images.Built], image_registry: str
) -> None:
    tool = images.builder()
    base = built_images["python"]
    # Under the build lock, so a parallel session's build never sees the base missing.
    with building.exclusive():
        tool.remove(base.local_reference)
        again = images.build(
            ["python"], registry_address=image_registry, progress=lambda line: None, lock_held=True
        )
    assert again["python"].outcome == "pulled"
    assert again["python"].image_id == base.image_id
    assert tool.image_id(base.local_reference) == base.image_id
    assert tool.inspect(base.registry_reference(image_registry)) is None, "the pull kept its address name"
