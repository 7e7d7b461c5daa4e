"""The SLAM skillset's ROS 2 node: queues LiDAR scans and serves the behaviors in `behaviors`.

Run with `python -m coral_skillsets.slam --plugins DIR [--params FILE]`. Parameters (node `slam`):
points_topic; end_of_data_topic (std_msgs/String JSON {"done", "published": {topic: count}} from
the bag player: the data ended once that many scans arrived); queue_size; scan_wait_s;
lookahead (most registered scans waiting for the tree; 0, the default: no bound); scans_per_call
(most registered scans one ProcessScan hands out, default 1); batch_wait_s (how long a
ProcessScan waits to fill its batch while a backlog is registered, default 0.05); map_path
(relative paths resolve against $CORAL_OUTPUT_DIR, else the working directory); max_range,
min_range, deskew, voxel_size (0: max_range/100), min_points, max_threads (KISS-ICP's; 0: all
cores); subscribe_on_enable.

Scans are queued from the moment the node starts, so none is lost before the tree enables
localization; with `subscribe_on_enable: true` the skillset subscribes to the points at the first
EnableLocalization instead, so a source that waits for its subscribers (the bag player) starts
when SLAM does (the benchmark uses this to keep the data path inside its clock).

While localization is enabled a worker thread registers scans as they come, as
Coral's SLAM skillsets run their SLAM between EnableLocalization and DisableLocalization; a
`ProcessScan` request only hands out results already computed (or waits for the next one), so a
slow or starved executor never holds registration up. The timing counters (`timings()`) end up in
the map's `.stats.json` next to the map, for the benchmark and for whoever tunes a deployment.
"""

from __future__ import annotations

import collections
import json
import math
import os
import threading
import time
from pathlib import Path
from typing import Any

from coral.lidar import clouds
from coral.sdk import CancelToken, Skillset
from coral.sdk.streams import RawStream
from coral_core import parsing
from coral_skillsets.slam import behaviors
from coral_skillsets.slam.core import MapFileError, ScanRejected, SlamConfig, SlamCore
from nav_msgs.srv import LoadMap
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import String
from std_srvs.srv import SetBool, Trigger

STATUS_PERIOD_S = 1.0


def output_path(value: str) -> Path:
    path = Path(os.path.expanduser(value))
    if path.is_absolute():
        return path
    return Path(os.environ.get("CORAL_OUTPUT_DIR", ".")) / path


class SlamSkillset(Skillset):
    NAME = "slam"
    BEHAVIORS = [
        behaviors.EnableLocalization,
        behaviors.DisableLocalization,
        behaviors.ProcessScan,
        behaviors.GetMappingDisplacement,
        behaviors.SaveMap,
        behaviors.LoadMap,
        behaviors.GetCurrentMap,
        behaviors.IsDataExhausted,
        behaviors.IsStopRequested,
    ]

    def on_start(self) -> None:
        voxel = float(self.param("voxel_size", 0.0))
        self.core = SlamCore(
            SlamConfig(
                max_range=float(self.param("max_range", 40.0)),
                min_range=float(self.param("min_range", 0.3)),
                deskew=bool(self.param("deskew", True)),
                voxel_size=voxel if voxel > 0 else None,
                min_points=int(self.param("min_points", 100)),
                max_threads=int(self.param("max_threads", 0)),
            )
        )
        self.map_path = str(self.param("map_path", "slam_map.ply"))
        self.scan_wait_s = float(self.param("scan_wait_s", 1.0))
        queue_size = int(self.param("queue_size", 2000))
        self.points_topic = str(self.param("points_topic", "/lidar/points"))
        # Scans stay serialised (CDR) until the worker decodes them, straight into numpy.
        self.queue: collections.deque[bytes] = collections.deque(maxlen=queue_size)
        self.typestore = clouds.cdr_typestore()
        clouds.warm_up(self.typestore)
        # One lock, two conditions: the worker waits for scans (`arrived`), a ProcessScan call for
        # the results it hands out (`results_ready`). A call waiting to fill its batch is woken once
        # the batch is full or the backlog is registered, not after every scan: each wake-up of a
        # service thread while KISS-ICP holds the interpreter lock costs registration a preemption
        # or more (docs/architecture.md, "Where the SLAM mission's CPU goes").
        lock = threading.RLock()
        self.arrived = threading.Condition(lock)
        self.results_ready = threading.Condition(lock)
        self.results_wanted: list[int] = []
        """How many results each waiting ProcessScan call needs before it wakes."""
        self.enabled = False
        self.source_done = False
        self.expected = 0
        self.received = 0
        self.first_arrival: float | None = None
        self.last_arrival: float | None = None
        self.first_registration: float | None = None
        self.last_delivered_at: float | None = None
        self.delivered = 0
        self.process_calls = 0  # ProcessScan requests served
        self.batch_wakeups = 0  # ProcessScan calls woken while filling their batch
        self.lookahead = max(0, int(self.param("lookahead", 0)))
        self.scans_per_call = max(1, int(self.param("scans_per_call", 1)))
        self.batch_wait_s = max(0.0, float(self.param("batch_wait_s", 0.05)))
        self.results: collections.deque[tuple[bool, dict[str, Any]]] = collections.deque()
        self.registering = False
        self.worker_stop = threading.Event()
        self.failed_scans = 0
        self.dropped = 0
        self.busy_s = 0.0  # in SlamCore.process: sanitising, registration, keyframe map
        self.decode_s = 0.0  # message buffer -> numpy arrays
        self.stalled_s = 0.0  # scans queued, but `lookahead` results already wait for the tree
        self.queued_at_start = 0  # scans already queued when the worker took the first one
        self.last_registered_at: float | None = None
        # This process's CPU time (all threads) over the same window as active_s.
        self.first_registration_cpu = self.last_delivered_cpu = 0.0
        self.points_qos = QoSProfile(
            depth=queue_size, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST
        )
        self.points_subscription: RawStream | None = None
        self.subscribe_on_enable = bool(self.param("subscribe_on_enable", False))
        if not self.subscribe_on_enable:
            self._subscribe_points()
        latched = QoSProfile(
            depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
        )
        self.create_subscription(
            String, str(self.param("end_of_data_topic", "/bag_player/done")), self.on_end, latched
        )
        self.status_publisher = self.create_publisher(String, "~/status", latched)
        self.published_state: tuple[bool, bool, bool] | None = None
        # A change the tree's conditions read is published at once (`publish_status`); the periodic
        # message only refreshes the counters, and each one wakes the executors' trees.
        self.create_timer(STATUS_PERIOD_S, self.publish_status)
        self.create_cancellable_service(SetBool, "~/set_localization", self.serve_set_localization)
        self.create_cancellable_service(Trigger, "~/process_scan", self.serve_process_scan)
        self.create_cancellable_service(Trigger, "~/displacement", self.serve_displacement)
        self.create_cancellable_service(Trigger, "~/mark_displacement", self.serve_mark_displacement)
        self.create_cancellable_service(Trigger, "~/save_map", self.serve_save_map)
        self.create_cancellable_service(LoadMap, "~/load_map", self.serve_load_map)
        self.create_cancellable_service(Trigger, "~/map_info", self.serve_map_info)
        self.worker = threading.Thread(target=self._work, name="slam-registration", daemon=True)
        self.worker.start()

    # Data in.
    def _subscribe_points(self) -> None:
        with self.arrived:
            if self.points_subscription is None:
                self.points_subscription = RawStream(
                    self, PointCloud2, self.points_topic, self.points_qos, self.on_scan, suffix="points"
                )

    def on_scan(self, message: bytes) -> None:
        with self.arrived:
            if len(self.queue) == self.queue.maxlen:
                self.dropped += 1
                if self.dropped == 1:
                    self.get_logger().warning(
                        f"Scan queue full ({self.queue.maxlen}): dropping the oldest scans (raise queue_size)"
                    )
            self.queue.append(message)
            self.received += 1
            self.last_arrival = time.monotonic()
            if self.first_arrival is None:
                self.first_arrival = self.last_arrival
            self.arrived.notify_all()

    def on_end(self, message: String) -> None:
        try:
            signal = parsing.load_json(message.data)
            done, published = bool(signal["done"]), dict(signal.get("published", {}))
        except (ValueError, KeyError, TypeError, AttributeError):
            self.get_logger().warning(f"Ignored a malformed end-of-data message: {message.data!r}")
            return
        if not done:
            return
        with self.arrived:
            self.source_done = True
            self.expected = int(published.get(self.points_topic, 0))
            self.arrived.notify_all()
            self.results_ready.notify_all()
        self.get_logger().info(
            f"End of data: {self.expected} scan(s) published, {self.received} received so far"
        )
        self.publish_status()

    @property
    def end_of_data(self) -> bool:
        """The source finished and every scan it published has arrived (call with `arrived` held)."""
        return self.source_done and self.received >= self.expected

    def status(self) -> dict[str, Any]:
        with self.arrived:
            queued, ready, busy = len(self.queue), len(self.results), self.registering
            ended = self.end_of_data
        return {
            "enabled": self.enabled,
            "received": self.received,
            "queued": queued,
            "processed": self.core.scans_processed,
            "delivered": self.delivered,
            "process_calls": self.process_calls,
            "failed": self.failed_scans,
            "dropped": self.dropped,
            "end_of_data": ended,
            "exhausted": ended and queued == 0 and ready == 0 and not busy,
            "active_s": (self.last_delivered_at - self.first_registration)
            if self.first_registration and self.last_delivered_at
            else 0.0,
        }

    def timings(self) -> dict[str, Any]:
        """Where the worker's time went, from the first scan it took to the last one handed out."""
        start, end = self.first_registration, self.last_delivered_at
        return {
            "registering_s": self.busy_s,
            "decoding_s": self.decode_s,
            "stalled_s": self.stalled_s,
            "batch_wakeups": self.batch_wakeups,
            "queued_at_start": self.queued_at_start,
            # Relative to the first registration: negative when scans queued up before it.
            "first_arrival_s": (self.first_arrival - start) if start and self.first_arrival else 0.0,
            "last_arrival_s": (self.last_arrival - start) if start and self.last_arrival else 0.0,
            "process_cpu_s": self.last_delivered_cpu - self.first_registration_cpu,
            "delivery_lag_s": (end - self.last_registered_at) if end and self.last_registered_at else 0.0,
            # The same window on the machine's monotonic clock, for tools that sample other
            # processes' CPU time over it (the benchmark's CPU table).
            "window_monotonic_s": [start or 0.0, end or 0.0],
        }

    def publish_status(self, only_if_changed: bool = False) -> None:
        """`only_if_changed`: only when what the tree's conditions read changed (IsDataExhausted
        must see the end at once); the counters alone wait for the periodic status, since every
        status message wakes the executors' trees for a tick."""
        status = self.status()
        state = (status["enabled"], status["end_of_data"], status["exhausted"])
        if only_if_changed and state == self.published_state:
            return
        self.published_state = state
        self.status_publisher.publish(String(data=json.dumps(status)))

    # Registration: the worker takes scans as they arrive while localization is enabled; it waits
    # for the tree only when `lookahead` (> 0) results are still undelivered.
    def _ready_to_register(self) -> bool:
        return self.enabled and bool(self.queue) and not self._results_full()

    def _results_full(self) -> bool:
        return 0 < self.lookahead <= len(self.results)

    def _results_due(self, latest_ok: bool) -> bool:
        """A waiting ProcessScan call has what it waits for (call with the lock held, after a result):
        its batch, a failed scan (which ends a batch), or the end of the registered backlog."""
        if not self.results_wanted:
            return False
        return not latest_ok or not self.queue or len(self.results) >= min(self.results_wanted)

    def _work(self) -> None:
        while not self.worker_stop.is_set():
            with self.arrived:
                while not self._ready_to_register():
                    if self.worker_stop.is_set():
                        return
                    stalled = self.enabled and bool(self.queue)
                    waited = time.perf_counter()
                    self.arrived.wait(0.1)
                    if stalled:
                        self.stalled_s += time.perf_counter() - waited
                message = self.queue.popleft()
                self.registering = True
                if self.first_registration is None:
                    self.first_registration = time.monotonic()
                    self.first_registration_cpu = time.process_time()
                    self.queued_at_start = len(self.queue) + 1
            outcome = self.register(message)
            with self.arrived:
                self.results.append(outcome)
                self.registering = False
                self.last_registered_at = time.monotonic()
                if self._results_due(outcome[0]):
                    self.results_ready.notify_all()

    def register(self, raw: bytes) -> tuple[bool, dict[str, Any]]:
        started = time.perf_counter()
        try:
            # rosbags reads the CDR bytes with the point data as a numpy view on them (no copy);
            # decode then converts it once to the float64 arrays KISS-ICP takes.
            message = self.typestore.deserialize_cdr(raw, "sensor_msgs/msg/PointCloud2")
        except Exception as err:  # noqa: BLE001 - rosbags raises several types for a malformed buffer
            self.failed_scans += 1
            self.get_logger().warning(f"Rejected an undecodable scan: {err}")
            return False, {"error": f"scan rejected: undecodable message: {err}", "stamp_ns": 0}
        stamp_ns = message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec
        try:
            points, times = clouds.decode(
                message.fields,
                message.data,
                message.point_step,
                message.width,
                message.height,
                message.is_bigendian,
            )
            decoded = time.perf_counter()
            self.decode_s += decoded - started
            result = self.core.process(points, times, stamp_ns)
            self.busy_s += time.perf_counter() - decoded
        except (ScanRejected, ValueError) as err:
            self.failed_scans += 1
            self.get_logger().warning(f"Rejected scan stamped {stamp_ns}: {err}")
            return False, {"error": f"scan rejected: {err}", "stamp_ns": stamp_ns}
        pose = result.pose
        yaw = math.atan2(float(pose[1, 0]), float(pose[0, 0]))
        return True, {
            "scans": self.core.scans_processed,
            "pose": [float(pose[0, 3]), float(pose[1, 3]), float(pose[2, 3]), yaw],
            "dropped": result.dropped,
            "stamp_ns": stamp_ns,
        }

    # Services.
    def serve_set_localization(self, request: Any, response: Any, token: CancelToken) -> Any:
        if request.data:
            self._subscribe_points()
        with self.arrived:
            self.enabled = bool(request.data)
            self.arrived.notify_all()
            self.results_ready.notify_all()
        response.success, response.message = True, json.dumps({"enabled": self.enabled})
        self.get_logger().info(f"Localization {'enabled' if self.enabled else 'disabled'}")
        return response

    def _next_result(self, token: CancelToken) -> tuple[bool, dict[str, Any]]:
        deadline = time.monotonic() + self.scan_wait_s
        with self.arrived:
            while not self.results:
                if self.end_of_data and not self.queue and not self.registering:
                    return False, {"error": "no more data"}
                remaining = deadline - time.monotonic()
                if remaining <= 0 or token.cancelled:
                    return False, {"error": f"no scan within {self.scan_wait_s:g} s"}
                self._wait_for_results(1, min(remaining, 0.05))
            return self.results.popleft()

    def _wait_for_results(self, count: int, timeout: float) -> None:
        self.results_wanted.append(count)
        try:
            self.results_ready.wait(timeout)
        finally:
            self.results_wanted.remove(count)

    def serve_process_scan(self, request: Any, response: Any, token: CancelToken) -> Any:
        """Hands out the next registered scan, plus those registered behind it (up to
        `scans_per_call`), so one behavior call can cover a burst of scans.

        While a backlog is being registered, the call waits up to `batch_wait_s` to fill its batch:
        a tree that is ahead of registration would otherwise wake up and round-trip once per scan,
        and on a small robot computer that chatter takes CPU from registration itself.
        """
        if not self.enabled:
            response.success, response.message = False, json.dumps({"error": "localization is disabled"})
            return response
        success, payload = self._next_result(token)
        taken = 1 if success else 0
        with self.arrived:
            deadline = time.monotonic() + self.batch_wait_s
            while success and taken < self.scans_per_call:
                if self.results and self.results[0][0]:
                    payload = self.results.popleft()[1]
                    taken += 1
                    continue
                remaining = deadline - time.monotonic()
                # Wait only for scans already on their way: a live sensor's next scan is not.
                backlog = not self.results and (self.queue or self.registering)
                if not (backlog and self.enabled) or remaining <= 0 or token.cancelled:
                    break
                self._wait_for_results(self.scans_per_call - taken, remaining)
                self.batch_wakeups += 1
            self.arrived.notify_all()
        payload["taken"] = taken
        self.process_calls += 1
        response.success, response.message = success, json.dumps(payload)
        if success:
            self.delivered += taken
            self.last_delivered_at = time.monotonic()
            self.last_delivered_cpu = time.process_time()
        self.publish_status(only_if_changed=True)
        return response

    def serve_displacement(self, request: Any, response: Any, token: CancelToken) -> Any:
        linear, angular = self.core.displacement()
        response.success, response.message = True, json.dumps({"linear": linear, "angular": angular})
        return response

    def serve_mark_displacement(self, request: Any, response: Any, token: CancelToken) -> Any:
        self.core.mark_displacement()
        response.success, response.message = True, "{}"
        return response

    def serve_save_map(self, request: Any, response: Any, token: CancelToken) -> Any:
        path = output_path(self.map_path)
        if self.core.scans_processed == 0 and not len(self.core.global_map()):
            # A process that registered nothing (one restarted mid-mission lost its map, or the data
            # never came) would write an empty map and let the mission report success.
            response.success = False
            response.message = json.dumps(
                {"error": "no map to save: this SLAM process has registered no scan and loaded no map"}
            )
            return response
        try:
            points = self.core.save_map(path)
        except MapFileError as err:
            response.success, response.message = False, json.dumps({"error": str(err)})
            return response
        # Throughput figures for benchmarks: active_s runs from the first registration to the last
        # scan handed to the tree, so it excludes start-up (processes, discovery, StartSLAM) and
        # the mission's closing steps, as KISS-ICP's own figure excludes its start-up.
        stats = {**self.status(), **self.timings(), "map_points": points}
        path.with_suffix(".stats.json").write_text(json.dumps(stats, indent=2) + "\n")
        self.get_logger().info(
            f"Saved map of {points} points and {self.core.scans_processed} poses to {path}"
        )
        response.success = True
        response.message = json.dumps(
            {"path": str(path), "points": points, "scans": self.core.scans_processed}
        )
        return response

    def serve_load_map(self, request: Any, response: Any, token: CancelToken) -> Any:
        path = output_path(request.map_url or self.map_path)
        try:
            points = self.core.load_map(path)
        except MapFileError as err:
            self.get_logger().error(str(err))
            response.result = (
                LoadMap.Response.RESULT_MAP_DOES_NOT_EXIST
                if not path.exists()
                else LoadMap.Response.RESULT_INVALID_MAP_DATA
            )
            return response
        self.get_logger().info(f"Loaded map of {points} points from {path}")
        response.result = LoadMap.Response.RESULT_SUCCESS
        return response

    def serve_map_info(self, request: Any, response: Any, token: CancelToken) -> Any:
        response.success = True
        response.message = json.dumps(
            {
                "local_points": len(self.core.local_map()),
                "global_points": len(self.core.global_map()),
            }
        )
        return response

    def on_stop(self) -> None:
        self.worker_stop.set()
        self.worker.join(timeout=10.0)
        if self.points_subscription is not None:
            self.points_subscription.close()
        status = self.status()
        self.get_logger().info(
            f"SLAM stopping: {status['processed']} scan(s) processed, {status['failed']} rejected, "
            f"{status['queued']} still queued; {self.busy_s:.2f} s registering"
        )
