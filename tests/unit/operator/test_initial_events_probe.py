"""How the operator tells an API server that streams a watch's initial objects from one that does
not: only the bookmark annotated as the end of the initial events says so. A server without
WatchList ignores `sendInitialEvents`, and its plain bookmarks must not be mistaken for it (kopf
would then wait for an end that never comes, and no index would ever fill)."""

from __future__ import annotations

import json
from typing import Any

from coral_operator.kube.watchlist import INITIAL_EVENTS_END, ends_initial_events


def _line(kind: str, annotations: dict[str, str] | None = None) -> bytes:
    metadata: dict[str, Any] = {"resourceVersion": "4711"}
    if annotations is not None:
        metadata["annotations"] = annotations
    event = {
        "type": kind,
        "object": {"kind": "CoralSystem", "apiVersion": "coral.dev/v1alpha1", "metadata": metadata},
    }
    return json.dumps(event).encode() + b"\n"


def test_the_annotated_bookmark_ends_the_initial_events() -> None:
    assert ends_initial_events([_line("ADDED", {}), _line("BOOKMARK", {INITIAL_EVENTS_END: "true"})])


def test_a_plain_bookmark_or_an_empty_stream_does_not() -> None:
    assert not ends_initial_events([_line("BOOKMARK"), b"\n", _line("BOOKMARK", {"other": "true"})])
    assert not ends_initial_events([])


def test_an_annotation_that_says_false_or_sits_on_another_event_does_not() -> None:
    assert not ends_initial_events([_line("BOOKMARK", {INITIAL_EVENTS_END: "false"})])
    assert not ends_initial_events([_line("MODIFIED", {INITIAL_EVENTS_END: "true"})])


def test_a_line_that_is_not_an_event_ends_the_question_with_no() -> None:
    assert not ends_initial_events(
        [b"<html>proxy error</html>\n", _line("BOOKMARK", {INITIAL_EVENTS_END: "true"})]
    )
