"""Recorded videos and folders of frames that are damaged: what decodes is read, in place."""

from __future__ import annotations

from pathlib import Path

import cv2
import pytest

from app.sources import files
from app.sources.files import InputError, open_input
from app.sources.synthetic import MovingObject, Scene
from tests.conftest import write_scene_video
from tests.sources.damaged_video import cut_after, garble_frames, jpeg_chunks

SCENE = Scene(
    name="walk",
    size=(320, 240),
    fps=20.0,
    frames=40,
    objects=(MovingObject((0, 100), (80.0, 0.0), (30, 44), 210),),
)


@pytest.fixture(scope="module")
def video(tmp_path_factory) -> Path:
    path = write_scene_video(SCENE, tmp_path_factory.mktemp("video") / "walk.avi")
    assert len(jpeg_chunks(path.read_bytes())) == SCENE.frames
    return path


def test_a_frame_that_does_not_decode_is_skipped_and_keeps_its_index(tmp_path, video):
    damaged = garble_frames(video, [7, 20, 21, 22], tmp_path / "damaged.avi")
    source = open_input(damaged)
    indexed = list(source.indexed_frames())
    assert [i for i, _ in indexed] == [i for i in range(40) if i not in (7, 20, 21, 22)]
    assert source.skipped == [7, 20, 21, 22]
    assert source.frames_read == 40 and source.header_frames == 40
    assert not source.ended_early
    # Frame 23 is the input's frame 23, not its 20th decodable one.
    whole = list(open_input(video).frames())
    assert cv2.absdiff(dict(indexed)[23], whole[23]).max() == 0


def test_the_first_frames_may_be_the_damaged_ones(tmp_path, video):
    source = open_input(garble_frames(video, [0, 1], tmp_path / "head.avi"))
    assert source.size == (320, 240)
    indexed = list(source.indexed_frames())
    assert indexed[0][0] == 2 and len(indexed) == 38 and source.skipped == [0, 1]


def test_a_long_run_of_bad_frames_ends_the_video_there(tmp_path, video, monkeypatch):
    monkeypatch.setattr(files, "MAX_BAD_RUN", 3)
    source = open_input(garble_frames(video, [10, 11, 12, 13], tmp_path / "run.avi"))
    assert [i for i, _ in source.indexed_frames()] == list(range(10))
    assert source.skipped == [] and source.frames_read == 10 and source.ended_early


def test_a_file_cut_short_ends_early_against_its_header(tmp_path, video):
    source = open_input(cut_after(video, 15, tmp_path / "cut.avi"))
    assert source.header_frames == 40
    decoded = len(list(source.frames()))
    assert decoded in (15, 16)  # The half JPEG at the cut may decode (its bottom grey).
    assert source.frames_read == decoded and source.skipped == [] and source.ended_early


def test_a_whole_video_does_not_end_early(video):
    source = open_input(video)
    assert len(list(source.frames())) == 40
    assert source.frames_read == 40 and not source.ended_early and source.skipped == []


def test_a_folder_image_that_does_not_decode_is_skipped_in_place(tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    for i in range(8):
        cv2.imwrite(str(folder / f"{i:03d}.png"), SCENE.frame(i))
    (folder / "000.png").write_bytes(b"not a picture")
    (folder / "004.png").write_bytes((folder / "004.png").read_bytes()[:40])
    (folder / "007.png").write_bytes(b"")
    source = open_input(folder)
    assert source.size == (320, 240)
    assert [i for i, _ in source.indexed_frames()] == [1, 2, 3, 5, 6]
    assert source.skipped == [0, 4, 7] and source.frames_read == 8 and not source.ended_early


def test_a_folder_of_images_none_of_which_decodes_is_refused(tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    for i in range(3):
        (folder / f"{i}.jpg").write_bytes(b"garbage")
    with pytest.raises(InputError, match="none of the 3 images"):
        open_input(folder)


def test_a_folder_where_only_one_image_decodes_is_refused_as_a_single_picture(tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    cv2.imwrite(str(folder / "0.png"), SCENE.frame(0))
    (folder / "1.png").write_bytes(b"garbage")
    with pytest.raises(InputError, match="only one of the 2 images"):
        open_input(folder)


@pytest.mark.parametrize("fps", [0.0, -3.0, float("nan"), float("inf"), 5000.0])
def test_a_frame_rate_out_of_range_is_refused(tmp_path, video, fps):
    with pytest.raises(InputError, match="frame rate"):
        open_input(video, fps)
    with pytest.raises(InputError, match="frame rate"):
        open_input(tmp_path, fps)
