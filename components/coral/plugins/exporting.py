"""Atomic export of a component's plugin into the shared plugin location (DESIGN section 4).

Called by `coral.sdk.component.Component` on start. The plugin is assembled in a hidden sibling
folder and renamed into place, so an executor scanning the location never sees half a plugin.
"""

from __future__ import annotations

import importlib.util
import inspect
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Iterable, Sequence
from pathlib import Path

import coral
from coral.plugins import compat, hashing
from coral.plugins import manifest as manifests


class ExportError(RuntimeError):
    """The component's declaration cannot be exported; the message names the class or package."""


def _module_file(module_name: str) -> Path:
    module = sys.modules.get(module_name)
    if module is None:
        module = importlib.import_module(module_name)
    source = inspect.getsourcefile(module)
    if source is None or getattr(module, "__path__", None) is not None:
        raise ExportError(
            f"module {module_name} must be a single .py file to be exported as a behavior module"
        )
    return Path(source)


def _interface_dir(package: str) -> Path:
    candidate = Path(package)
    if candidate.is_dir():
        return candidate
    spec = importlib.util.find_spec(package)
    if spec is None or not spec.submodule_search_locations:
        raise ExportError(f"interface package {package!r} is neither a directory nor an importable package")
    return Path(next(iter(spec.submodule_search_locations)))


def _copy_modules(module_names: Iterable[str], target: Path) -> dict[str, str]:
    """Copies each module's file into `target`; returns original module name -> exported module name."""
    target.mkdir(parents=True, exist_ok=True)
    exported: dict[str, str] = {}
    for module_name in module_names:
        if module_name in exported:
            continue
        short = module_name.rsplit(".", 1)[-1]
        if short in exported.values():
            raise ExportError(f"two exported modules are both named {short!r}; rename one of them")
        shutil.copyfile(_module_file(module_name), target / f"{short}.py")
        exported[module_name] = short
    (target / "__init__.py").touch()
    return exported


def build_manifest(
    component: manifests.ComponentRef,
    behavior_classes: Sequence[type],
    module_names: dict[str, str],
    files: dict[str, str],
    interface_packages: list[str],
) -> manifests.PluginManifest:
    from coral.sdk import declaring

    entries = [declaring.describe_behavior(cls, module_names[cls.__module__]) for cls in behavior_classes]
    seen: set[str] = set()
    for entry in entries:
        if entry.id in seen:
            raise ExportError(f"component {component.name} declares node ID {entry.id!r} twice")
        seen.add(entry.id)
    return manifests.PluginManifest(
        schema_version=manifests.SCHEMA_VERSION,
        component=component,
        coral_version=coral.__version__,
        ros_distro=compat.current_ros_distro(),
        behaviors=entries,
        files=files,
        interface_packages=interface_packages,
        exported_at=time.time(),
    )


def _swap_into_place(staged: Path, final: Path) -> None:
    """Renames `staged` to `final`; an existing export is renamed aside first, then removed."""
    if final.exists():
        retired = final.parent / f".{final.name}.old-{os.getpid()}-{time.monotonic_ns()}"
        os.rename(final, retired)
        os.rename(staged, final)
        shutil.rmtree(retired, ignore_errors=True)
    else:
        os.rename(staged, final)


def export_plugin(
    plugins_root: Path,
    component: manifests.ComponentRef,
    behavior_classes: Sequence[type] = (),
    *,
    extra_modules: Sequence[str] = (),
    interface_packages: Sequence[str] = (),
) -> Path:
    """Exports behaviors and interface packages to `<plugins_root>/<component name>/`; returns that folder."""
    plugins_root.mkdir(parents=True, exist_ok=True)
    staged = Path(tempfile.mkdtemp(prefix=f".{component.name}.tmp-", dir=plugins_root))
    try:
        modules = [cls.__module__ for cls in behavior_classes] + list(extra_modules)
        module_names = _copy_modules(modules, staged / manifests.BEHAVIORS_DIR)
        exported_interfaces: list[str] = []
        for package in interface_packages:
            source = _interface_dir(package)
            destination = staged / manifests.INTERFACES_DIR / source.name
            shutil.copytree(source, destination, ignore=shutil.ignore_patterns("__pycache__"))
            exported_interfaces.append(source.name)
        manifest = build_manifest(
            component,
            behavior_classes,
            module_names,
            hashing.hash_tree(staged),
            sorted(exported_interfaces),
        )
        (staged / manifests.MANIFEST_NAME).write_text(manifest.to_json(), encoding="utf-8")
        staged.chmod(0o755)
        final = plugins_root / component.name
        _swap_into_place(staged, final)
        return final
    except BaseException:
        shutil.rmtree(staged, ignore_errors=True)
        raise


def mark_ready(plugin_dir: Path, text: str) -> None:
    """Writes the `ready` marker atomically (readiness probes test for its existence)."""
    marker = plugin_dir / manifests.READY_NAME
    staged = plugin_dir / f".{manifests.READY_NAME}.{os.getpid()}"
    staged.write_text(text, encoding="utf-8")
    os.replace(staged, marker)


def clear_ready(plugin_dir: Path) -> None:
    (plugin_dir / manifests.READY_NAME).unlink(missing_ok=True)
