"""Decoding ahead (``read_ahead``): the same frames, in order, with the same errors where
they were, a bounded number waiting, and a source closed when its reader stops early."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import pytest

from app.sources.files import open_input
from app.sources.read_ahead import read_ahead
from tests.conftest import write_scene_video
from tests.sources.damaged_video import garble_frames
from tests.sources.test_sources_files import SCENE


def test_a_damaged_video_reads_the_same_ahead_as_in_step(tmp_path: Path) -> None:
    video = write_scene_video(SCENE, tmp_path / "walk.avi")
    damaged = garble_frames(video, [0, 7, 20, 21], tmp_path / "damaged.avi")
    in_step, ahead = open_input(damaged), open_input(damaged)
    expected = list(in_step.indexed_frames())
    got = list(ahead.indexed_frames(ahead=4))
    assert [i for i, _ in got] == [i for i, _ in expected]
    assert all(cv2.absdiff(a, b).max() == 0 for (_, a), (_, b) in zip(got, expected, strict=True))
    assert ahead.skipped == in_step.skipped == [0, 7, 20, 21]
    assert ahead.frames_read == in_step.frames_read == 40


def counted(count: int, made: list[int], fail_at: int | None = None) -> Iterator[int]:
    for item in range(count):
        if item == fail_at:
            raise ValueError(f"item {item} is bad")
        made.append(item)
        yield item


def test_an_error_of_the_source_is_raised_after_the_items_before_it() -> None:
    got: list[int] = []
    with pytest.raises(ValueError, match="item 5 is bad"):
        for item in read_ahead(counted(10, [], fail_at=5), depth=3):
            got.append(item)
    assert got == [0, 1, 2, 3, 4]


def test_no_more_than_depth_items_wait_for_a_slow_consumer() -> None:
    made: list[int] = []
    items = read_ahead(counted(100, made), depth=3)
    assert next(items) == 0
    time.sleep(0.3)  # Time for the reader to run far ahead, were it not bounded.
    # The one taken, three waiting and one in the reader's hand, waiting for room.
    assert len(made) <= 5
    assert list(items) == list(range(1, 100))


def test_stopping_early_ends_the_reader_and_closes_the_source() -> None:
    closed = threading.Event()

    def source() -> Iterator[int]:
        try:
            yield from range(1000)
        finally:
            closed.set()

    before = threading.active_count()
    items = read_ahead(source(), depth=2)
    assert [next(items) for _ in range(3)] == [0, 1, 2]
    items.close()
    assert closed.is_set(), "the source was not closed"
    assert threading.active_count() == before, "the reader thread is still there"
