"""The bag player's core: recorded order, recorded spacing divided by the rate, prompt stop."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest
from coral.lidar import generating
from coral_drivers.bag_player import playing


class FakeClock:
    """A clock the stop event advances: `wait(s)` moves time by s instead of sleeping."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class AdvancingEvent(threading.Event):
    def __init__(self, clock: FakeClock) -> None:
        super().__init__()
        self.clock = clock

    def wait(self, timeout: float | None = None) -> bool:
        self.clock.now += timeout or 0.0
        return self.is_set()


def _messages(stamps_s: list[float]) -> list[tuple[str, str, int, bytes]]:
    return [("/t", "std_msgs/msg/String", int(s * 1e9), b"x") for s in stamps_s]


@pytest.mark.parametrize(
    ("rate", "expected"), [(1.0, [0.0, 0.1, 0.3]), (2.0, [0.0, 0.05, 0.15]), (0.0, [0, 0, 0])]
)
def test_messages_keep_their_recorded_spacing_divided_by_the_rate(rate: float, expected: list[float]) -> None:
    clock = FakeClock()
    published: list[float] = []
    report = playing.play(
        iter(_messages([10.0, 10.1, 10.3])),
        lambda topic, msgtype, raw: published.append(clock.now),
        rate=rate,
        stop=AdvancingEvent(clock),
        clock=clock,
    )
    assert published == pytest.approx(expected)
    assert report.messages == 3 and report.per_topic == {"/t": 3} and not report.stopped_early


def test_a_stop_request_ends_playing_before_the_next_message() -> None:
    clock = FakeClock()
    stop = AdvancingEvent(clock)
    published: list[bytes] = []

    def publish(topic: str, msgtype: str, raw: bytes) -> None:
        published.append(raw)
        stop.set()

    report = playing.play(iter(_messages([0.0, 1.0, 2.0])), publish, rate=1.0, stop=stop, clock=clock)
    assert len(published) == 1 and report.stopped_early


def test_a_generated_bag_is_read_in_recorded_order(short_dataset: Path) -> None:
    topics = {t.name: t for t in playing.read_topics(short_dataset / "bag")}
    assert topics[generating.POINTS_TOPIC].count == 40
    messages = list(playing.iterate(short_dataset / "bag", [generating.POINTS_TOPIC]))
    stamps = [stamp for _, _, stamp, _ in messages]
    assert len(messages) == 40 and stamps == sorted(stamps)
    assert {msgtype for _, msgtype, _, _ in messages} == {"sensor_msgs/msg/PointCloud2"}


def test_a_missing_topic_or_bag_is_named(short_dataset: Path, tmp_path: Path) -> None:
    with pytest.raises(playing.BagError, match="no topic"):
        list(playing.iterate(short_dataset / "bag", ["/nope"]))
    with pytest.raises(playing.BagError, match=str(tmp_path / "missing")):
        playing.read_topics(tmp_path / "missing")
