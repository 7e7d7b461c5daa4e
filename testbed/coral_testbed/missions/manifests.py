"""Prepares an example mission for a given cluster: robot names, ROS domain and trees' timeouts, and
names the robot files a mission expects (the bag, the site share).

Pure text/YAML functions. Used by `coral demo` and the mission tests, which run the committed
examples with their own robot names; `stack.MissionView` puts the files on the robots.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[3]
SLAM_MISSION = ROOT / "examples" / "lidar-slam" / "mission.yaml"
RELAY_MISSION = ROOT / "examples" / "relay" / "mission.yaml"
SITE_MISSION = ROOT / "examples" / "site" / "mission.yaml"
SLAM_ROBOT = "robot-1"
RELAY_ROBOTS = ("relay-survey", "relay-server", "relay-worker")
SITE_ROBOTS = {
    "site-survey": "survey-rover",
    "site-server": "server",
    "site-quadruped": "quadruped",
    "site-arm": "arm",
}
"""The site example's robots and their models (`coral.dev/model`), which pick their overrides."""
SITE_LABEL = "coral.dev/site=plant-a"
"""The label the site example's CoralSystem selects its robots by."""
BAGS = "/var/lib/coral/bags"
"""The robot folder the examples' bag players read (an administrator opens it per namespace)."""
SLAM_BAG = f"{BAGS}/lidar-slam"
CONTAINER_OUTPUT_DIR = "/var/lib/coral/output"
"""$CORAL_OUTPUT_DIR in the component images (components/Dockerfile): where the SLAM skillset's
container writes the map and trajectory."""
SURVEY_BAG = f"{BAGS}/survey"
SITE_SHARE = "/srv/maps"


def rename_robots(text: str, names: dict[str, str]) -> str:
    """The manifest with each robot name replaced (selectors, hostnames in trees, system names)."""
    for old in sorted(names, key=len, reverse=True):
        text = re.sub(rf"(?<![\w-]){re.escape(old)}(?![\w-])", names[old], text)
    return text


def documents(text: str) -> list[dict[str, Any]]:
    return [d for d in yaml.safe_load_all(text) if d]


class _BlockDumper(yaml.SafeDumper):
    """Keeps trees and parameters as readable block scalars, so the text stays greppable."""


def _text(dumper: yaml.SafeDumper, value: str) -> yaml.Node:
    return dumper.represent_scalar("tag:yaml.org,2002:str", value, style="|" if "\n" in value else None)


_BlockDumper.add_representer(str, _text)


def _dump(docs: list[dict[str, Any]]) -> str:
    return yaml.dump_all(docs, Dumper=_BlockDumper, sort_keys=False, width=110)


def with_domain(text: str, domain: int) -> str:
    """Every CoralSystem of the manifest on ROS domain `domain` (tests get a private one)."""
    docs = documents(text)
    for doc in docs:
        doc["spec"].setdefault("ros", {})["domainId"] = domain
    return _dump(docs)


def with_timeout(text: str, process: str, timeout_ms: int) -> str:
    """The `timeout_ms` of every `WaitForRemoteTrigger` for `process` set to `timeout_ms`."""
    pattern = rf'(<WaitForRemoteTrigger process_identifier="{re.escape(process)}" timeout_ms=")\d+(")'
    result, count = re.subn(pattern, rf"\g<1>{timeout_ms}\g<2>", text)
    if not count:
        raise ValueError(f"no WaitForRemoteTrigger for {process!r} in the mission")
    return result


def only_systems(text: str, names: set[str]) -> str:
    """The manifest restricted to the CoralSystems named in `names`."""
    return _dump([d for d in documents(text) if d["metadata"]["name"] in names])
