"""What the operator counts as it works: passes by kind and result, their durations, how late they
start, and API requests by verb, resource and code; registered on the registry given."""

from __future__ import annotations

from prometheus_client import CollectorRegistry, Counter, Histogram

from coral_operator.metrics.requests import request_info

# Passes take milliseconds to seconds (a system pass over a thousand robots); waits for a worker
# reach the queue's spacing and backoff (up to 30 s).
DURATION_BUCKETS_S = (0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0)


class OperatorMetrics:
    """The operator's counters and histograms; label values are bounded by kinds, verbs and codes."""

    def __init__(self, registry: CollectorRegistry) -> None:
        self.reconciles = Counter(
            "coral_operator_reconciles",
            "Reconcile passes by kind (CoralSystem, CoralInstance) and result (success, error).",
            ["kind", "result"],
            registry=registry,
        )
        self.reconcile_duration = Histogram(
            "coral_operator_reconcile_duration_seconds",
            "How long a reconcile pass ran, by kind.",
            ["kind"],
            buckets=DURATION_BUCKETS_S,
            registry=registry,
        )
        self.queue_wait = Histogram(
            "coral_operator_workqueue_queue_duration_seconds",
            "How long a due key waited for a free worker before its pass started, by kind.",
            ["kind"],
            buckets=DURATION_BUCKETS_S,
            registry=registry,
        )
        self.api_requests = Counter(
            "coral_operator_api_requests",
            "Requests the operator's passes made to the API server by verb, resource and HTTP code "
            "(0: no answer). kopf's watches are not counted.",
            ["verb", "resource", "code"],
            registry=registry,
        )

    def observe_pass(self, kind: str, failed: bool, late_s: float, busy_s: float) -> None:
        self.reconciles.labels(kind, "error" if failed else "success").inc()
        self.reconcile_duration.labels(kind).observe(busy_s)
        self.queue_wait.labels(kind).observe(late_s)

    def observe_request(self, method: str, url: str, code: int) -> None:
        verb, resource = request_info(method, url)
        self.api_requests.labels(verb, resource, str(code)).inc()
