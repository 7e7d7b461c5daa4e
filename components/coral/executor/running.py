"""The executor process: load a tree, wait for its node types, tick it, report status, halt cleanly.

Called by `python -m coral.executor` and `coral executor` (`coral.executor.cli`). Exit codes:
0 tree SUCCESS, 1 tree FAILURE, 2 bad input (tree, parameters), 3 error while ticking (a
behavior raised), 4 internal error, 5 node types still missing after `--wait-timeout`,
128+N stopped by signal N (the tree is halted first).
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from coral_core.limits import DEFAULT_NO_PROGRESS_S

from coral.executor import plugins_phase, records, sinks
from coral.executor.halting import HaltSignal, park_builder
from coral.executor.ticking import TickLoop
from coral.sdk.heap import freeze_startup_heap
from coral.stop_signals import relay_stop_signals

LOG = logging.getLogger(__name__)
EXIT_SUCCESS = 0
EXIT_FAILURE = 1
EXIT_BAD_INPUT = 2
EXIT_TICK_ERROR = 3
EXIT_INTERNAL = 4
EXIT_WAIT_TIMEOUT = 5
# Before the first tick, how long to wait for the instance's `spec.halt`: a robot halted before
# its executor (re)started must not tick once; a robot out of reach starts after this.
FIRST_HALT_READING_S = 5.0


@dataclass
class ExecutorOptions:
    tree: Path
    plugins: Path
    params: Path | None = None
    rate_hz: float = 10.0
    no_progress_s: float = DEFAULT_NO_PROGRESS_S
    status_jsonl: Path | None = None
    main_tree: str | None = None
    hostname: str = field(default_factory=lambda: os.environ.get("CORAL_HOSTNAME") or socket.gethostname())
    node_name: str = "coral_executor"
    status_topic: str = "/coral/tree_status"
    extra_sinks: list[str] = field(default_factory=list)
    wait_timeout_s: float | None = None
    liveness_wait_s: float = 10.0
    groot2_port: int | None = None
    groot2_host: str = "127.0.0.1"
    groot2_allow_hooks: bool = False
    groot2_wait_s: float = 0.0
    metrics_port: int | None = None
    metrics_host: str = "0.0.0.0"
    verbose: bool = False


class _Stop:
    """Signal bookkeeping: which signal asked us to stop, and whom to wake."""

    def __init__(self) -> None:
        self.event = threading.Event()
        self.signum = 0
        self.wake: Any = None

    def install(self) -> None:
        def stopped(signum: int) -> None:
            self.signum = signum
            self.event.set()
            if self.wake is not None:
                self.wake()

        relay_stop_signals(stopped)


def _emit(fanout: sinks.SinkFanout, event: str, **fields: Any) -> None:
    fanout.emit({"ts": time.time(), "event": event, **fields})


def _build_sinks(options: ExecutorOptions) -> sinks.SinkFanout:
    fanout = sinks.SinkFanout([sinks.TerminalSink(verbose=options.verbose)])
    if options.status_jsonl is not None:
        fanout.add(sinks.JsonLinesSink(options.status_jsonl))
    for target in options.extra_sinks:
        fanout.add(sinks.load_sink(target, {"hostname": options.hostname, "tree": str(options.tree)}))
    return fanout


def _serve_metrics(options: ExecutorOptions, fanout: sinks.SinkFanout) -> Callable[[float], None] | None:
    """With `--metrics-port`, serve the executor's metrics, fed by the status records as a sink;
    what the tick loop tells of each tick, or None."""
    if options.metrics_port is None:
        return None
    from prometheus_client import CollectorRegistry

    from coral.executor.metrics import ExecutorMetrics

    metrics = ExecutorMetrics(CollectorRegistry())
    metrics.serve(options.metrics_host, options.metrics_port)
    fanout.add(metrics)
    return metrics.observe_tick


def _check_ros_names(options: ExecutorOptions) -> None:
    """Raises rclpy's own error for a node name or status topic ROS would refuse, before anything
    starts, so it reads as bad input rather than a crash of the executor."""
    from rclpy.expand_topic_name import expand_topic_name
    from rclpy.validate_full_topic_name import validate_full_topic_name
    from rclpy.validate_node_name import validate_node_name

    validate_node_name(options.node_name)
    validate_full_topic_name(expand_topic_name(options.status_topic, options.node_name, "/"))


def run_executor(options: ExecutorOptions) -> int:
    from coral_core import bt
    from rclpy.exceptions import NameValidationException

    from coral.sdk import params

    try:
        fanout = _build_sinks(options)
        on_tick = _serve_metrics(options, fanout)
    except (OSError, ValueError) as err:
        print(f"error: {err}")
        return EXIT_BAD_INPUT
    stop = _Stop()
    stop.install()
    _emit(
        fanout,
        "started",
        tree=str(options.tree),
        plugins=str(options.plugins),
        hostname=options.hostname,
        pid=os.getpid(),
        main_tree=options.main_tree,
    )
    try:
        _check_ros_names(options)
        if options.params is not None:
            params.validate_file(options.params)
        document = bt.load_tree_file(options.tree, None, main_tree=options.main_tree)
    except (bt.BTError, params.ParamsError, NameValidationException) as err:
        _emit(fanout, "error", message=str(err))
        _emit(fanout, "finished", root_status="IDLE", exit_code=EXIT_BAD_INPUT, tick_count=0)
        fanout.close()
        return EXIT_BAD_INPUT
    try:
        return _run_with_ros(options, document, fanout, stop, on_tick)
    except Exception as err:  # noqa: BLE001 - must not read as a tree FAILURE (exit 1)
        _emit(fanout, "error", message=f"{type(err).__name__}: {err}")
        _emit(fanout, "finished", root_status="ERROR", exit_code=EXIT_INTERNAL, tick_count=0)
        traceback.print_exc()
        return EXIT_INTERNAL
    finally:
        fanout.close()


def _run_with_ros(
    options: ExecutorOptions,
    document: Any,
    fanout: sinks.SinkFanout,
    stop: _Stop,
    on_tick: Callable[[float], None] | None = None,
) -> int:
    from coral_core import bt

    from coral import coordination
    from coral.coordination.hub import CoordinationHub
    from coral.executor.context import ExecutorContext
    from coral.plugins import compat
    from coral.sdk import calls

    wake = threading.Event()
    waker: dict[str, Any] = {"tree": None}

    def wake_up() -> None:
        tree = waker["tree"]
        if tree is not None:
            tree.wake_up()
        wake.set()

    stop.wake = wake_up
    publisher = None
    halts = HaltSignal(wake_up)
    follower = _follow_halts(halts)
    context = ExecutorContext(
        node_name=options.node_name, hostname=options.hostname, params_file=options.params, wake_up=wake_up
    )
    ros_sink = sinks.RosTopicSink(context.node, options.status_topic)
    try:
        fanout.add(ros_sink)
        context.coordination = CoordinationHub(context.node, options.hostname, wake_up)
        registry = bt.NodeRegistry.with_builtins()
        coordination.register(registry)
        state = plugins_phase.PluginState(
            used=document.node_types_used(), builtin_ids=set(registry.node_ids())
        )
        missing = _wait_for_node_types(
            options, document, registry, state, fanout, stop, wake, compat.current_ros_distro()
        )
        if stop.event.is_set():
            _emit(fanout, "finished", root_status="IDLE", exit_code=128 + stop.signum, tick_count=0)
            return 128 + stop.signum
        if missing:
            _emit(
                fanout,
                "error",
                message="Node types still missing after the wait timeout: " + ", ".join(missing),
            )
            _emit(fanout, "finished", root_status="IDLE", exit_code=EXIT_WAIT_TIMEOUT, tick_count=0)
            return EXIT_WAIT_TIMEOUT
        problems = bt.validate_document(document, registry)
        if problems:
            for problem in problems:
                _emit(fanout, "error", message=str(problem))
            _emit(fanout, "finished", root_status="IDLE", exit_code=EXIT_BAD_INPUT, tick_count=0)
            return EXIT_BAD_INPUT
        try:
            tree = bt.build_tree(document, registry, context=context)
        except bt.BTError as err:
            _emit(fanout, "error", message=str(err))
            _emit(fanout, "finished", root_status="IDLE", exit_code=EXIT_BAD_INPUT, tick_count=0)
            return EXIT_BAD_INPUT
        calls.open_clients(tree.nodes)
        waker["tree"] = tree
        loop = TickLoop(
            tree,
            context,
            fanout,
            state,
            rate_hz=options.rate_hz,
            no_progress_s=options.no_progress_s,
            halts=halts,
            build_park=park_builder(document, registry, context),
            on_tick=on_tick,
        )
        publisher = _start_groot2(options, tree, fanout)
        if publisher is not None:

            def release_and_wake() -> None:
                publisher.hooks.close()  # a stop must not wait at a breakpoint
                wake_up()

            stop.wake = release_and_wake
        freeze_startup_heap()  # the tree and its plugins are built: nothing of them is garbage
        loop.wait_for_components(options.liveness_wait_s, stop.event)
        if follower is not None:
            halts.wait_known(FIRST_HALT_READING_S)
        if publisher is not None and options.groot2_wait_s > 0:
            connected = publisher.wait_for_client(options.groot2_wait_s, stop.event)
            _emit(fanout, "groot2", port=options.groot2_port, client_connected=connected)
        return loop.run(stop.event, lambda: 128 + stop.signum)
    finally:
        if follower is not None:
            follower.stop()
        if publisher is not None:
            publisher.close()
        # The ROS sink goes first, while its node still exists, so tools get the final records.
        fanout.remove(ros_sink)
        ros_sink.close()
        context.shutdown()


def _follow_halts(halts: HaltSignal) -> Any:
    """In a cluster (CORAL_INSTANCE and CORAL_NAMESPACE set), a started watch of the instance's
    `spec.halt`; None elsewhere (`coral run`, a tree run by hand), where nothing halts the tree."""
    if not (os.environ.get("CORAL_INSTANCE") and os.environ.get("CORAL_NAMESPACE")):
        return None
    from coral.executor.halt_watch import InstanceHaltWatch
    from coral.executor.kubernetes_sink import executor_api_client, instance_address

    namespace, instance = instance_address({})
    try:
        follower = InstanceHaltWatch(executor_api_client(), namespace, instance, halts)
    except Exception as error:  # noqa: BLE001 - without credentials the tree runs, unhaltable
        LOG.warning("Not following spec.halt of CoralInstance %s/%s: %s", namespace, instance, error)
        return None
    follower.start()
    return follower


def _start_groot2(options: ExecutorOptions, tree: Any, fanout: sinks.SinkFanout) -> Any:
    """The Groot2 publisher when `--groot2-port` asks for one (a port in use is reported, and the
    tree runs without it)."""
    if options.groot2_port is None:
        return None
    import struct

    import zmq
    from coral_core.bt.groot2 import Groot2Publisher

    try:
        publisher = Groot2Publisher(
            tree, options.groot2_port, host=options.groot2_host, allow_hooks=options.groot2_allow_hooks
        )
    except (zmq.ZMQError, struct.error) as err:  # a port in use; a tree beyond 65,535 nodes (uint16 uids)
        _emit(fanout, "error", message=f"Groot2 publisher not started on port {options.groot2_port}: {err}")
        return None
    _emit(
        fanout,
        "groot2",
        port=options.groot2_port,
        host=options.groot2_host,
        hooks=options.groot2_allow_hooks,
        tree_uuid=publisher.tree_uuid.hex(),
    )
    return publisher


def _wait_for_node_types(
    options: ExecutorOptions,
    document: Any,
    registry: Any,
    state: plugins_phase.PluginState,
    fanout: sinks.SinkFanout,
    stop: _Stop,
    wake: threading.Event,
    ros_distro: str,
) -> list[str]:
    """Polls the plugin location until nothing is missing, a stop, or the wait timeout; returns missing."""
    deadline = None if options.wait_timeout_s is None else time.monotonic() + options.wait_timeout_s
    last_plugins: dict[str, Any] | None = None
    last_missing: list[str] | None = None
    state.plugins_ready = None
    reminded_at = time.monotonic()
    # Hand-written rather than a tenacity retry: a wake (a plugin exported) or a stop ends each
    # pause early, and every pass reports what changed, not only the last outcome.
    while True:
        plugins_phase.refresh(state, registry, options.plugins, ros_distro)
        plugins_record = state.record()
        if plugins_record != last_plugins:
            _emit(fanout, **plugins_record)
            last_plugins = plugins_record
        missing = sorted(document.missing_node_types(registry))
        now = time.monotonic()
        if missing != last_missing or (missing and now - reminded_at > 10.0):
            reminded_at = now
            previous = state.plugins_ready
            condition = records.plugins_ready_condition(previous, missing, time.time())
            if missing:
                _emit(fanout, "waiting", missing=missing)
            if previous is None or (condition.status, condition.message) != (
                previous.status,
                previous.message,
            ):
                _emit(fanout, "condition", **condition.as_dict())
            state.plugins_ready = condition
            last_missing = missing
        if not missing or stop.event.is_set():
            return missing
        if deadline is not None and now >= deadline:
            return missing
        wake.wait(0.5)
        wake.clear()
