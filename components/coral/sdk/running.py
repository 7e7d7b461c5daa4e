"""Runs one component process: node, plugin export, readiness, heartbeat, clean shutdown.

Called by `python -m coral.sdk.run` / `coral skillset`, and by a component's own `__main__`
through `run_component`. Readiness contract: once the node exists and its plugin is exported,
`<plugins>/<name>/ready` is written and the log line `Component <name> ready` is printed; both go
away (marker removed) on shutdown. Exit codes: 0 (or `request_stop`'s), 2 bad input (parameters,
component name, export), 3 the component's own code raised.
"""

from __future__ import annotations

import importlib
import signal
import sys
import threading
import traceback
from pathlib import Path
from types import FrameType
from typing import Any

from coral.plugins import exporting
from coral.sdk import dds, params, topics
from coral.sdk.heap import freeze_startup_heap
from coral.sdk.spinning import Spinner

EXIT_BAD_INPUT = 2
EXIT_CRASHED = 3


def load_component_class(target: str) -> type:
    """`package.module:ClassName` -> the class, with a clear error when either part is wrong."""
    module_name, _, class_name = target.partition(":")
    if not module_name or not class_name:
        raise ValueError(f"component {target!r} must be written MODULE:CLASS")
    module = importlib.import_module(module_name)
    try:
        cls: type = getattr(module, class_name)
    except AttributeError:
        raise ValueError(f"module {module_name} has no class {class_name}") from None
    return cls


def export_component(
    component_class: type, plugins_dir: Path, *, name: str | None = None, namespace: str | None = None
) -> Path:
    """Exports a component's plugin without starting ROS (to bake it into an image for
    Kubernetes image volumes); no `ready` marker is written. Returns the plugin folder."""
    from coral.plugins import manifest as manifests
    from coral.sdk.component import default_component_name

    component_name = name or getattr(component_class, "NAME", None) or default_component_name(component_class)
    ref = manifests.ComponentRef(
        name=component_name,
        kind=getattr(component_class, "KIND", "skillset"),
        node_name=component_name,
        namespace=namespace or "/",
    )
    return exporting.export_plugin(
        plugins_dir,
        ref,
        list(getattr(component_class, "BEHAVIORS", ())),
        extra_modules=list(getattr(component_class, "EXPORT_MODULES", ())),
        interface_packages=list(getattr(component_class, "INTERFACE_PACKAGES", ())),
    )


class _StopSignal(Exception):
    """Raised by the signal handlers into the main thread's final wait, which it ends at once."""


def _install_signal_handlers(stop: threading.Event, waiting: list[bool]) -> None:
    """SIGINT and SIGTERM set `stop`; while `waiting[0]`, they also end the main thread's wait.

    The handler runs on the main thread, between two of its bytecodes: it must not set the event
    that thread waits on, whose lock that thread may hold at that moment. It raises instead, as
    Ctrl-C raises KeyboardInterrupt out of a wait.
    """

    def handle(signum: int, _frame: FrameType | None) -> None:
        stop.set()
        if waiting[0]:
            waiting[0] = False  # one raise: a second signal must not interrupt the first's handling
            raise _StopSignal

    signal.signal(signal.SIGINT, handle)
    signal.signal(signal.SIGTERM, handle)


def _wait_for_stop(stop: threading.Event, requested: threading.Event, waiting: list[bool]) -> None:
    """Blocks until a signal or a stop request, with no wake-up in between: a component's main
    thread that looked at a flag ten times a second woke about forty times a second once it had to
    wait for the interpreter lock too, each time taking a core from whatever the component runs
    (docs/architecture.md, "Where the SLAM mission's CPU goes")."""
    try:
        waiting[0] = True
        if not stop.is_set():
            requested.wait()
    except _StopSignal:
        pass
    finally:
        waiting[0] = False


def run_component(
    component_class: type,
    *,
    plugins_dir: Path | None,
    params_file: Path | None = None,
    name: str | None = None,
    namespace: str | None = None,
    threads: int = 4,
) -> int:
    """Runs the component until SIGINT/SIGTERM or `request_stop`; returns the process exit code."""
    import rclpy
    from rclpy.duration import Duration
    from rclpy.exceptions import NameValidationException
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    from std_msgs.msg import String

    if params_file is not None:
        try:
            params.validate_file(params_file)
        except params.ParamsError as err:
            print(f"error: {err}", file=sys.stderr)
            return EXIT_BAD_INPUT

    stop = threading.Event()
    waiting = [False]
    _install_signal_handlers(stop, waiting)
    dds.use_coral_profile(large_messages=bool(getattr(component_class, "LARGE_MESSAGES", False)))
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    component: Any = None
    plugin_dir: Path | None = None
    try:
        component = component_class(name=name, namespace=namespace, params_file=params_file)
        logger = component.get_logger()
        component.on_start()
        if plugins_dir is not None:
            plugin_dir = exporting.export_plugin(
                plugins_dir,
                component.component_ref,
                list(component.BEHAVIORS),
                extra_modules=list(component.EXPORT_MODULES),
                interface_packages=list(component.INTERFACE_PACKAGES),
            )
        heartbeat_publisher = component.create_publisher(String, topics.HEARTBEAT_TOPIC, 10)

        def beat(state: str = "alive") -> None:
            heartbeat_publisher.publish(String(data=component.heartbeat(state).encode()))

        component.create_timer(topics.HEARTBEAT_PERIOD_S, beat)
        beat()
        logger.info(
            f"Component {component.component_name} ready: {component.KIND} exported "
            f"{len(component.BEHAVIORS)} behavior(s) to {plugin_dir}"
        )
        print(f"Component {component.component_name} ready", flush=True)
        # The marker comes last, so whoever sees it can also see the log lines above.
        if plugin_dir is not None:
            exporting.mark_ready(plugin_dir, f"{component.component_name}\n")

        executor = MultiThreadedExecutor(num_threads=threads)
        executor.add_node(component)
        freeze_startup_heap()
        spinner = Spinner(executor, "ros-spin", on_error=component.stop_requested.set).start()
        # The main thread only waits, until a signal or a stop request.
        _wait_for_stop(stop, component.stop_requested, waiting)
        spinner.stop()
        if spinner.error is not None:
            raise spinner.error
        if plugin_dir is not None:
            exporting.clear_ready(plugin_dir)
        beat("stopping")
        # Executors fail calls at once on `stopping`; make sure it leaves before the node goes.
        heartbeat_publisher.wait_for_all_acked(Duration(seconds=1))
        logger.info(f"Component {component.component_name} stopping")
        component.on_stop()
        executor.shutdown(timeout_sec=1.0)
        return component.exit_code or 0
    except (ValueError, exporting.ExportError, NameValidationException) as err:
        print(f"error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except Exception:  # noqa: BLE001 - a crash in the component's own code gets its own exit code
        traceback.print_exc()
        return EXIT_CRASHED
    finally:
        if plugin_dir is not None:
            exporting.clear_ready(plugin_dir)
        if component is not None:
            component.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
