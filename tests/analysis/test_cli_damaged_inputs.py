"""`vigil analyze` on damaged files, odd frame sizes and bad option values, as a user runs it."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from app import cli
from app.sources.synthetic import MovingObject, Scene
from tests.analysis.walker import WALKER, vigil
from tests.conftest import decode_all
from tests.sources.damaged_video import cut_after, garble_frames


def _report(out: Path) -> dict:
    return json.loads((out / "report.json").read_text())


def _rows(out: Path) -> list[dict[str, str]]:
    with (out / "tracks.csv").open() as handle:
        return list(csv.DictReader(handle))


@pytest.mark.parametrize("quiet", [True, False], ids=["quiet", "summary"])
def test_a_frame_that_does_not_decode_is_skipped_and_the_analysis_carries_on(
    tmp_path, walker_video, quiet
):
    damaged = garble_frames(walker_video, [20], tmp_path / "damaged.avi")
    out = tmp_path / "out"
    result = vigil("analyze", damaged, "--out", out, *(["--quiet"] if quiet else []))
    assert result.returncode == 0, result.stderr
    (line,) = result.stderr.splitlines()  # Said once, --quiet or not.
    assert line.startswith("vigil analyze: warning: 1 frame did not decode")
    assert "frame 20" in line
    report = _report(out)
    assert report["frames"] == WALKER.frames - 1 and report["frames_read"] == WALKER.frames
    assert report["skipped_frames"] == [20] and report["header_frames"] == WALKER.frames
    assert report["ended_early"] is False and report["warnings"] == [line.split("warning: ")[1]]
    assert report["duration_s"] == pytest.approx(WALKER.frames / WALKER.fps)
    assert 20 not in [s["frame"] for s in report["frame_stats"]]
    assert "Warning: 1 frame did not decode" in (out / "report.html").read_text()
    # The walker is tracked to the end (frame 50), each row at its decode index and time.
    rows = _rows(out)
    frames = {int(r["frame"]) for r in rows}
    assert 20 not in frames and max(frames) >= 45
    for row in rows:
        assert float(row["time_s"]) == pytest.approx(int(row["frame"]) / WALKER.fps, abs=1e-3)
        (box,) = WALKER.truth(int(row["frame"]))
        assert abs(int(row["x"]) - box.box.x) <= 4
    (track,) = report["tracks"]
    assert track["mean_speed_px_s"] == pytest.approx(60.0, rel=0.05)
    # annotated.avi stays frame for frame with the input: the skipped one repeats frame 19.
    annotated = list(decode_all(out / "annotated.avi"))
    assert len(annotated) == WALKER.frames
    assert cv2.absdiff(annotated[20], annotated[19]).max() == 0
    assert cv2.absdiff(annotated[21], annotated[19]).max() > 0


def test_evaluate_rescores_a_folder_with_a_skipped_frame_as_analyze_scored_it(
    tmp_path, walker_video, box_truth
):
    damaged = garble_frames(walker_video, [20, 21, 22], tmp_path / "damaged.avi")
    out = tmp_path / "out"
    assert vigil("analyze", damaged, "--out", out, "--truth", box_truth, "--quiet").returncode == 0
    result = vigil("evaluate", out, "--truth", box_truth)
    assert result.returncode == 0, result.stderr
    # The skipped frames are no misses, and the last frames are scored too.
    assert json.loads(result.stdout)["objects"] == _report(out)["evaluation"]["objects"]


def test_many_damaged_frames_are_each_counted(tmp_path, walker_video):
    bad = [0, 10, 11, 12, 30, 74]
    out = tmp_path / "out"
    result = vigil("analyze", garble_frames(walker_video, bad, tmp_path / "d.avi"), "--out", out)
    assert result.returncode == 0, result.stderr
    (line,) = result.stderr.splitlines()
    assert "5 frames did not decode" in line and "frames 0, 10, 11, 12, 30" in line
    report = _report(out)
    # The last frame is the file's end as far as the reader can tell: not a skipped one.
    assert report["skipped_frames"] == bad[:-1] and report["frames_read"] == WALKER.frames - 1
    assert report["frames"] == WALKER.frames - len(bad)
    assert len(list(decode_all(out / "annotated.avi"))) == WALKER.frames - 1


def test_truncated_video_is_analysed_up_to_where_it_breaks_and_says_so(tmp_path, walker_video):
    cut = cut_after(walker_video, 37, tmp_path / "cut.avi")  # the header still claims 75
    out = tmp_path / "out"
    result = vigil("analyze", cut, "--out", out, "--quiet")
    assert result.returncode == 0, result.stderr
    # FFmpeg's complaints about the cut stay out; Vigil's own line says what happened.
    (line,) = result.stderr.splitlines()
    report = _report(out)
    decoded = report["frames"]
    assert decoded in (37, 38)  # The half JPEG at the cut may decode.
    assert line == (
        f"vigil analyze: warning: the video ended early: {decoded} frames decoded of the "
        f"{WALKER.frames} its header claims (cut short, or damaged from frame {decoded} on)"
    )
    assert report["ended_early"] is True and report["header_frames"] == WALKER.frames
    assert report["frames_read"] == decoded and report["skipped_frames"] == []


def test_a_whole_video_has_no_warnings(tmp_path, walker_video):
    result = vigil("analyze", walker_video, "--out", tmp_path / "out", "--quiet")
    assert result.returncode == 0 and result.stderr == ""
    report = _report(tmp_path / "out")
    assert report["warnings"] == [] and report["skipped_frames"] == []
    assert report["ended_early"] is False and report["frames_read"] == WALKER.frames


ODD = Scene(
    name="odd",
    size=(251, 191),
    fps=15.0,
    frames=30,
    objects=(MovingObject((20, 80), (75.0, 0.0), (30, 40), 220, first_frame=2),),
)


def test_an_odd_frame_size_is_kept_in_the_annotated_video(tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    for i in range(ODD.frames):
        cv2.imwrite(str(folder / f"{i:03d}.png"), ODD.frame(i))
    out = tmp_path / "out"
    result = vigil("analyze", folder, "--out", out, "--fps", "15", "--quiet")
    assert result.returncode == 0, result.stderr
    annotated = list(decode_all(out / "annotated.avi"))
    assert len(annotated) == ODD.frames
    assert {f.shape for f in annotated} == {(191, 251, 3)}
    assert cv2.imread(str(out / "snapshots" / "event-0001.jpg")).shape == (191, 251, 3)
    assert len(list(decode_all(out / "annotated.mp4"))) == ODD.frames  # 252x192: H.264's even.
    # Pixel for pixel the input's frame (up to JPEG), not a shifted or scaled copy: the
    # last column and row are there.
    for index in (0, 15):
        drawn = annotated[index].astype(int)
        source = ODD.frame(index).astype(int)
        unmarked = (np.abs(drawn - source).max(axis=2) < 40).mean()
        assert unmarked > 0.9, index
        assert np.abs(drawn[:, -1] - source[:, -1]).mean() < 8
        assert np.abs(drawn[-1] - source[-1]).mean() < 8


@pytest.mark.parametrize(
    ("option", "value", "reason"),
    [
        (
            "--fps",
            "-3",
            "--fps: must be a positive number of frames per second, at most 1000, not -3",
        ),
        ("--fps", "0", "--fps: must be a positive number"),
        ("--fps", "nan", "--fps: not a finite number"),
        ("--fps", "inf", "--fps: not a finite number"),
        ("--fps", "5000", "at most 1000"),
        ("--fps", "fast", "--fps: not a number"),
        ("--detect-width", "7", "--detect-width: the detection width is 0 (full size) or 32 to"),
        ("--detect-width", "-320", "--detect-width: the detection width is 0 (full size)"),
        ("--detect-width", "10000", "32 to 7680 pixels, not 10000"),
        ("--detect-width", "1.5", "--detect-width: not a whole number"),
        ("--min-area", "-5", "--min-area: must be 0 or more"),
        ("--min-area", "nan", "--min-area: not a finite number"),
        ("--min-area", "inf", "--min-area: not a finite number"),
        ("--sensitivity", "nan", "--sensitivity: sensitivity is a grey-level threshold"),
        ("--sensitivity", "0", "--sensitivity: sensitivity is a grey-level threshold"),
        ("--denoise-kernel", "4", "--denoise-kernel: invalid choice"),
    ],
)
def test_a_bad_option_value_exits_2_with_one_line_before_anything_runs(
    tmp_path, capsys, option, value, reason
):
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exited:
        cli.main(["analyze", str(tmp_path), "--out", str(out), option, value])
    assert exited.value.code == 2
    captured = capsys.readouterr()
    (line,) = captured.err.splitlines()
    assert reason in line and line.startswith("vigil analyze: error: argument ")
    assert not out.exists()


@pytest.mark.parametrize("width", ["0", "32"])
def test_the_smallest_detection_widths_are_accepted(tmp_path, walker_video, width):
    out = tmp_path / "out"
    result = vigil("analyze", walker_video, "--out", out, "--detect-width", width, "--quiet")
    assert result.returncode == 0, result.stderr
    assert _report(out)["settings"]["detect_width"] == int(width)


def test_a_min_area_larger_than_the_frame_fails_with_the_frame_s_size(tmp_path, walker_video):
    # No object could cover it: detection would be off, the report empty, and no reason.
    out = tmp_path / "out"
    result = vigil("analyze", walker_video, "--out", out, "--min-area", "1e9", "--quiet")
    assert result.returncode != 0
    (line,) = result.stderr.splitlines()
    assert "min_area 1e+09 px is more than a frame of this video holds (320x240" in line, line
    assert not (out / "report.json").exists()
