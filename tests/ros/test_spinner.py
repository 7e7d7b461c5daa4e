"""A `Spinner` runs a node's callbacks for as long as the component lives without holding anything per
callback (a component runs for days on a robot), and `stop` ends it at once."""

from __future__ import annotations

import gc
import threading
import time

import pytest
from coral_testbed.waiting import wait_for

pytestmark = pytest.mark.ros

TIMER_PERIOD_S = 0.005


@pytest.mark.parametrize("kind", ["single", "multi"])
def test_a_spinner_holds_nothing_per_callback_and_stops_at_once(ros_env: dict[str, str], kind: str) -> None:
    import rclpy
    from coral.sdk.spinning import Spinner
    from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node("spinner_test", context=context)
        calls = [0]
        node.create_timer(TIMER_PERIOD_S, lambda: calls.__setitem__(0, calls[0] + 1))
        executor = (
            SingleThreadedExecutor(context=context)
            if kind == "single"
            else MultiThreadedExecutor(num_threads=2, context=context)
        )
        executor.add_node(node)
        spinner = Spinner(executor, "ros-spin").start()

        def objects_after(count: int) -> int:
            wait_for(lambda: calls[0] >= count, timeout=30, interval=0.01, message=f"{count} timer callbacks")
            gc.collect()
            return len(gc.get_objects())

        before = objects_after(100)
        after = objects_after(500)
        # rclpy's spin loop hangs two callbacks on its future per callback run: 800 more objects
        # here, millions over a robot's week, if the spinner's future kept them.
        assert after - before < 200, f"{after - before} more objects after 400 more callbacks"

        asked = time.monotonic()
        spinner.stop(timeout_s=5.0)
        assert time.monotonic() - asked < 1.0
        assert not any(thread.name == "ros-spin" for thread in threading.enumerate())
        assert spinner.error is None
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
