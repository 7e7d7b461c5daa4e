"""Maps the project's import packages onto their folders (see the README's Layout section), and
registers each one's `coral` verbs and components where it lives.

Each role has one import package living in its own source root, so the folder names
(`operator/`, `components/skillsets/`, ...) never become import names themselves. Container images
copy only the roots they run; an absent root is skipped with its entry points, so the `coral`
command inside an image offers only the verbs that image can run.
"""

from pathlib import Path

from setuptools import find_packages, setup

PACKAGE_ROOTS = {
    "coral_core": "components/core",
    "coral": "components/coral",
    "coral_skillsets": "components/skillsets",
    "coral_drivers": "components/drivers",
    "coral_operator": "operator/coral_operator",
    "coral_testbed": "testbed/coral_testbed",
}

# Entry points by the root that holds them: the `coral` script, `coral.verbs` are the `coral` command's verbs
# (`coral_core.command`), `coral.logs` how each side reads logs for `coral logs` (`coral_core.logs_verb`),
# `coral.components` how `coral run` finds an installed component from the
# image name in a compose file.
ENTRY_POINTS: dict[str, dict[str, list[str]]] = {
    "coral_core": {
        "console_scripts": ["coral = coral_core.command:main"],
        "coral.verbs": ["logs = coral_core.logs_verb:logs_command"],
    },
    "coral": {
        "coral.verbs": [
            "run = coral.local.cli:run_command",
            "ps = coral.local.cli:ps_command",
            "stop = coral.local.cli:stop_command",
            "validate = coral.local.cli:validate_command",
            "verify = coral.local.cli:verify_command",
            "nodes-model = coral.local.cli:nodes_model_command",
            "generate-bag = coral.lidar.cli:generate_bag_command",
            "slam-demo = coral.lidar.cli:slam_demo_command",
            "executor = coral.executor.cli:executor_command",
            "skillset = coral.sdk.cli:skillset_command",
            "plugins = coral.plugins.cli:plugins_command",
            "offline-agent = coral.offline.cli:offline_agent_command",
        ],
        "coral.logs": ["run = coral.local.cli:LOGS_OF_RUNS"],
    },
    "coral_skillsets": {
        "coral.components": [
            "slam-skillset = coral_skillsets.slam.skillset:SlamSkillset",
            "snapshot-skillset = coral_skillsets.snapshot.skillset:SnapshotSkillset",
        ],
    },
    "coral_drivers": {
        "coral.components": ["bag-player = coral_drivers.bag_player.driver:BagPlayer"],
    },
    "coral_operator": {
        "coral.verbs": [
            "operator = coral_operator.cli:operator_command",
            "convert = coral_operator.convert.cli:convert_command",
            "crds = coral_operator.crds_cli:crds_command",
            "rollout = coral_operator.rollout_cli:rollout",
            "halt = coral_operator.halt_cli:halt_command",
            "resume = coral_operator.halt_cli:resume_command",
            "groot2 = coral_operator.groot2_cli:groot2_command",
            "tree = coral_operator.tree_cli:tree_group",
            "config = coral_operator.config_cli:config_command",
        ],
        "coral.logs": ["system = coral_operator.logs_cli:LOGS_OF_SYSTEMS"],
    },
    "coral_testbed": {
        "coral.verbs": [
            "dev-cluster = coral_testbed.devcluster:dev_cluster",
            "images = coral_testbed.images.cli:images",
            "demo = coral_testbed.missions.cli:demo_command",
        ],
    },
}


def present_roots(base: Path) -> list[str]:
    """The import packages whose source root is in this copy of the repository."""
    return [name for name, path in PACKAGE_ROOTS.items() if (base / path).is_dir()]


def packages(roots: list[str]) -> list[str]:
    found: list[str] = []
    for name in roots:
        found.append(name)
        found.extend(f"{name}.{sub}" for sub in find_packages(PACKAGE_ROOTS[name]))
    return found


def entry_points(roots: list[str]) -> dict[str, list[str]]:
    """The entry points of `roots` only, by group."""
    groups: dict[str, list[str]] = {}
    for name in roots:
        for group, entries in ENTRY_POINTS.get(name, {}).items():
            groups.setdefault(group, []).extend(entries)
    return groups


if __name__ == "__main__":
    roots = present_roots(Path(__file__).parent)
    setup(
        packages=packages(roots),
        package_dir={name: PACKAGE_ROOTS[name] for name in roots},
        entry_points=entry_points(roots),
    )
