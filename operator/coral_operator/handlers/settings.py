"""Operator-wide kopf settings and the controller's lifetime, from startup to cleanup.

Progress goes to `coral.dev/` annotations (status belongs to the CRD schema, which would prune
kopf's own fields); no diff-base is kept (no change handlers); no finalizers, so a stopped
operator never blocks a deletion.
"""

from __future__ import annotations

import logging
from typing import Any

import kopf
from coral_core import names

from coral_operator import config
from coral_operator.handlers.filters import watch_selectors
from coral_operator.kube import applying, client, watchlist
from coral_operator.metrics.fleet import FleetCollector
from coral_operator.metrics.instruments import OperatorMetrics
from coral_operator.planning import pods, rbac
from coral_operator.reconcile.controller import Controller

LIST_CHUNK_SIZE = 50
"""Objects per page of kopf's initial listings."""


class EssenceFreeDiffBase(kopf.AnnotationsDiffBaseStorage):
    """A diff-base that never builds an object's essence.

    kopf compares essences only for change handlers (on.create/update/resume/delete), and this
    operator registers none: only event handlers and indexes. kopf still builds one from a deep
    copy of every watched body on every event, which at a thousand robots (pods with their
    managed fields, instances with their status) is the largest cost per event.
    """

    def build(self, *, body: kopf.Body, extra_fields: Any = None) -> Any:
        return {}

    def fetch(self, *, body: kopf.Body) -> Any:
        return None


@kopf.on.startup()
def configure_operator(settings: kopf.OperatorSettings, **_: Any) -> None:
    settings.persistence.progress_storage = kopf.AnnotationsProgressStorage(prefix=names.GROUP)
    settings.persistence.diffbase_storage = EssenceFreeDiffBase(
        prefix=names.GROUP, key="last-handled-configuration"
    )
    # Events of one object are handled after this quiet spell; the default 0.1 s adds that much
    # to every hop of a robot's ordered startup, and the work queues do the coalescing anyway.
    settings.batching.batch_window = 0.02
    # Only warnings become Kubernetes Events automatically; the handlers post their own.
    settings.posting.level = logging.WARNING
    settings.execution.max_workers = 16
    settings.watching.server_timeout = 300
    # Where the API server cannot stream a watch's initial objects (`wait_for_the_coral_api`), a
    # listing comes in pages: a namespace's CoralSystems may each be a megabyte, and one response
    # with all of them (its text and its decoded objects at once) would be the operator's largest
    # moment (docs/architecture.md, "The operator's memory").
    settings.watching.chunk_size = LIST_CHUNK_SIZE
    for resource, selector in watch_selectors().items():
        settings.watching.label_selectors[resource] = selector
    settings.networking.request_timeout = 60


@kopf.on.startup()
def wait_for_the_coral_api(
    settings: kopf.OperatorSettings, memo: kopf.Memo, logger: logging.Logger, **_: Any
) -> None:
    # Watching a CRD whose storage is still initializing can leave an index unfilled for good,
    # which holds every handler back; start watching only once both kinds are served.
    namespaces = list(memo.get("namespaces", []))
    # An API server that is slow or restarting is asked again a second later: kopf would wait a
    # minute after any other error before this operator serves anything.
    try:
        problem = applying.coral_api_served(namespaces)
        if problem is not None:
            raise kopf.TemporaryError(f"Waiting for the coral.dev API: {problem}", delay=1)
        streamed = watchlist.initial_events_streamed(namespaces[0] if namespaces else None)
    except client.NO_ANSWER as error:
        raise kopf.TemporaryError(f"Waiting for the API server: {error}", delay=1) from error
    settings.watching.initial_streaming = streamed
    logger.info(
        "The API server streams each watch's objects one at a time (sendInitialEvents)."
        if streamed
        else f"The API server does not stream a watch's objects (WatchList off): listing them "
        f"in pages of {LIST_CHUNK_SIZE}."
    )


def _post(reference: dict[str, Any], kind: str, reason: str, message: str) -> None:
    # kopf.event, not kopf.info: the posting level (WARNING) keeps kopf's own chatter out, not ours.
    kopf.event(reference, type=kind, reason=reason, message=message)


@kopf.on.startup()
def create_controller(memo: kopf.Memo, **_: Any) -> None:
    # Its workers start with the first watch event (`handlers.watching`), in a handler's context,
    # where kopf's Event poster lives.
    client.load_api_classes()
    settings = config.from_environment()
    # Metrics are on when `main` was given an address to serve them on, and then cost a counter
    # per pass and per request; the fleet's state is read only when Prometheus scrapes.
    registry = memo.get("metrics_registry")
    metrics = OperatorMetrics(registry) if registry is not None else None
    controller = Controller(
        policy=settings.policy,
        post=_post,
        pod_settings=pods.PodSettings(policy=settings.policy, helper_image=settings.helper_image),
        preflight_registries=settings.preflight_registries,
        on_pass=None if metrics is None else metrics.observe_pass,
    )
    if metrics is not None:
        client.count_requests(metrics.observe_request)
        registry.register(FleetCollector(controller.indexes, controller.queue))
    memo["controller"] = controller


@kopf.on.cleanup()
def stop_controller(memo: kopf.Memo, **_: Any) -> None:
    controller = memo.get("controller")
    if controller is not None:
        controller.stop()


@kopf.on.startup()
def confine_the_executors(**_: Any) -> None:
    # Before any system's account exists: its Role alone would let an executor patch every
    # instance of its namespace; the policy narrows that to its own robot's (`planning.rbac`).
    try:
        applying.ensure_admission_policy(rbac.build_admission_policy(), rbac.POLICY_HASH_ANNOTATION)
    except Exception as error:
        refused = applying.refusal(error)
        if refused is None:
            raise
        raise kopf.PermanentError(
            f"The executors' admission policy {rbac.POLICY_NAME} is missing or out of date and this "
            f"operator may not write it ({refused}); install it with the chart or deploy/coral-operator.yaml."
        ) from error
