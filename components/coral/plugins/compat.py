"""Compatibility of a manifest with the running executor: the paper's version check, in Python.

Pure functions, called by `discovery.discover`; `current_ros_distro` reads the environment once.
"""

from __future__ import annotations

import importlib.metadata
import os

import coral
from coral.plugins import manifest as manifests


def major_of(version: str) -> str:
    """Major component of a dotted version; for 0.x releases the minor counts too (semver rule)."""
    parts = version.split(".")
    if parts[0] == "0" and len(parts) > 1:
        return f"0.{parts[1]}"
    return parts[0]


def current_ros_distro() -> str:
    """The ROS distro of this Python environment: `ROS_DISTRO`, else the installed rclpy wheel's name."""
    distro = os.environ.get("ROS_DISTRO")
    if distro:
        return distro
    for dist in importlib.metadata.distributions():
        name = (dist.metadata["Name"] or "").lower()
        if name.startswith("ros-") and name.endswith("-rclpy") and name.count("-") == 2:
            return name.split("-")[1]
    return "unknown"


def incompatibility(
    manifest: manifests.PluginManifest,
    *,
    coral_version: str = coral.__version__,
    ros_distro: str,
) -> str | None:
    """Why this executor must refuse the manifest, or None when it may load it."""
    if manifest.schema_version != manifests.SCHEMA_VERSION:
        return (
            f"manifest schema version {manifest.schema_version} is not supported "
            f"(this executor reads version {manifests.SCHEMA_VERSION})"
        )
    if major_of(manifest.coral_version) != major_of(coral_version):
        return (
            f"exported for Coral {manifest.coral_version}, this executor runs Coral {coral_version} "
            f"(major versions {major_of(manifest.coral_version)} and {major_of(coral_version)} differ)"
        )
    if manifest.ros_distro != ros_distro:
        return f"exported for ROS {manifest.ros_distro}, this executor runs ROS {ros_distro}"
    return None
