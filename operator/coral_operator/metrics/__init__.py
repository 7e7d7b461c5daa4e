"""The operator's Prometheus metrics (docs/metrics.md).

`instruments` counts what happens (passes, API requests) on a registry created by `main` and
passed in; `fleet` reads the controller's indexes and queue when Prometheus scrapes, so the state
of robots, instances and rollouts costs nothing between scrapes; `requests` names an API request's
verb and resource. Label values are bounded by kinds, verbs, states and systems, never by robots.
"""
