"""Image entrypoints of the reference components, for the robot runner (which runs no images).

The pods Coral's operator creates for `coral/slam-skillset:0.1.0` and friends carry no command:
the image's ENTRYPOINT would supply it. The runner needs the same argv as local processes; it is
derived from the local runtime's table of reference components, so both stay one list. Used by
`MissionStack`.
"""

from __future__ import annotations

from coral.local.components import REFERENCE_COMPONENTS

# The plugin folder the Dockerfiles pass; the runner rewrites it to the robot's plugin hostPath.
PLUGIN_DIR = "/var/lib/coral/plugins"


def reference_entrypoints() -> dict[str, list[str]]:
    """Image name (no tag) -> `python -m <package> --plugins /var/lib/coral/plugins`, as the Dockerfiles."""
    entrypoints: dict[str, list[str]] = {}
    for image, target in REFERENCE_COMPONENTS.items():
        package = target.split(":")[0].rsplit(".", 1)[0]
        entrypoints[image] = ["python", "-m", package, "--plugins", PLUGIN_DIR]
    # The examples skillset's image is published as both names in the examples and tests.
    if "coral/example-skillset" in entrypoints:
        entrypoints.setdefault("coral/examples-skillset", entrypoints["coral/example-skillset"])
    return entrypoints
