"""Every query of the shipped Grafana dashboard returns series from a real Prometheus that scrapes
the operator's and an executor's metrics endpoints (served here in-process over a fleet as the
operator's indexes hold it) and evaluates the shipped recording rules. The cluster test
(tests/integration/kind/test_metrics_scraped_by_prometheus_on_kind.py) asks the same of a real fleet."""

from __future__ import annotations

import time

from coral.executor.metrics import ExecutorMetrics
from coral_operator import main
from coral_operator.metrics.fleet import FleetCollector
from coral_operator.metrics.instruments import OperatorMetrics
from coral_testbed.waiting import wait_for
from fixtures.prometheus import Prometheus, dashboard_queries, free_port
from metrics_fleet import Queue, fleet
from prometheus_client import CollectorRegistry, start_http_server


def test_every_dashboard_query_returns_series_from_a_real_prometheus(prometheus: Prometheus) -> None:
    operator_port, executor_port = free_port(), free_port()
    registry = main.metrics_registry()
    server, thread = start_http_server(operator_port, addr="127.0.0.1", registry=registry)
    registry.register(FleetCollector(fleet(3), Queue(depth=1, wait_s=0.0)))
    operator = OperatorMetrics(registry)
    operator.observe_pass("CoralSystem", False, 0.001, 0.05)
    operator.observe_request("POST", "https://h/api/v1/namespaces/robots/pods", 201)
    executor = ExecutorMetrics(CollectorRegistry())
    executor.serve("127.0.0.1", executor_port)
    try:
        executor.emit(
            {
                "event": "plugins",
                "loaded": [{"component": "s", "behaviors": ["Count"]}],
                "refused": [],
                "conflicts": [],
            }
        )
        executor.emit({"event": "status", "root_status": "RUNNING"})
        executor.emit(
            {
                "event": "transition",
                "path": "Main/Count",
                "node_id": "Count",
                "previous": "IDLE",
                "status": "RUNNING",
            }
        )
        executor.emit(
            {
                "event": "transition",
                "path": "Main/Count",
                "node_id": "Count",
                "previous": "RUNNING",
                "status": "SUCCESS",
            }
        )
        executor.observe_tick(0.002)
        began = time.time()
        prometheus.start(
            {
                "coral-operator": [f"127.0.0.1:{operator_port}"],
                "coral-executor": [f"127.0.0.1:{executor_port}"],
            },
            alert_for={},
        )

        def without_series() -> list[str]:
            return [
                f"{title}: {expr}"
                for title, expr in dashboard_queries()
                if not prometheus.query_range(expr, began)
            ]

        wait_for(
            lambda: not without_series(),
            timeout=30,
            message=lambda: "dashboard queries without series:\n" + "\n".join(without_series()),
        )
    finally:
        executor.close()
        server.shutdown()
        server.server_close()
        thread.join(timeout=5)
