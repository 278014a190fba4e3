"""`vigil analyze` and `vigil evaluate` as a user runs them: a real process on real files."""

from __future__ import annotations

import csv
import json
import os
import statistics
from pathlib import Path

import av
import cv2
import numpy as np
import pytest

from app.analysis.runner import FITTING_ROWS, AnalysisOptions, analyze
from app.sources.synthetic import MovingObject, Scene
from tests.analysis.walker import WALKER, vigil
from tests.conftest import decode_all, write_scene_video

HEADER = "frame,time_s,track_id,x,y,w,h,cx,cy,area,distance_px,speed_px_s"


@pytest.fixture(scope="module")
def analysed(tmp_path_factory, walker_video, box_truth) -> Path:
    out = tmp_path_factory.mktemp("out")
    result = vigil("analyze", walker_video, "--out", out, "--masks", "--truth", box_truth)
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    return out


def read_tracks(out: Path) -> list[dict[str, str]]:
    with (out / "tracks.csv").open() as handle:
        return list(csv.DictReader(handle))


def test_tracks_csv_has_exact_header_and_boxes_in_input_pixels(analysed):
    assert (analysed / "tracks.csv").read_text().splitlines()[0] == HEADER
    rows = read_tracks(analysed)
    assert rows, "the walker was not tracked"
    frames = [int(r["frame"]) for r in rows]
    assert min(frames) <= 5 and max(frames) <= 50
    for row in rows:
        truth = {t.box for t in WALKER.truth(int(row["frame"]))}
        assert truth, f"a detection on frame {row['frame']}, where nothing moves"
        (box,) = truth
        found = (int(row["x"]), int(row["y"]), int(row["w"]), int(row["h"]))
        assert abs(found[0] - box.x) <= 4 and abs(found[1] - box.y) <= 4
        assert float(row["time_s"]) == pytest.approx(int(row["frame"]) / WALKER.fps, abs=1e-3)


def test_speed_is_measured_within_five_percent(analysed):
    report = json.loads((analysed / "report.json").read_text())
    (track,) = report["tracks"]
    assert track["mean_speed_px_s"] == pytest.approx(60.0, rel=0.05)
    settled = [float(r["speed_px_s"]) for r in read_tracks(analysed)[8:-3]]
    assert statistics.median(settled) == pytest.approx(60.0, rel=0.05)


def test_every_output_file_has_the_mode_a_new_file_gets(analysed):
    umask = os.umask(0o022)
    os.umask(umask)
    files = [p for p in analysed.rglob("*") if p.is_file()]
    expected = {"report.json", "events.json", "tracks.csv", "annotated.avi", "annotated.mp4"}
    assert expected <= {p.name for p in files}
    modes = {p.relative_to(analysed).as_posix(): oct(p.stat().st_mode & 0o777) for p in files}
    assert set(modes.values()) == {oct(0o666 & ~umask)}, modes


def test_the_report_sums_up_each_track_as_tracks_csv_has_it(analysed):
    report = json.loads((analysed / "report.json").read_text())
    rows = read_tracks(analysed)
    for track in report["tracks"]:
        mine = [r for r in rows if int(r["track_id"]) == track["track_id"]]
        speeds = [float(r["speed_px_s"]) for r in mine]
        assert track["frames"] == len(mine)
        assert track["first_frame"] == int(mine[0]["frame"])
        # The largest after the first rows' speeds, fitted to a few sightings.
        settled = speeds[FITTING_ROWS:] or speeds
        assert track["max_speed_px_s"] == pytest.approx(max(settled), abs=2e-3)
        assert track["mean_speed_px_s"] == pytest.approx(statistics.fmean(settled), abs=2e-3)
        distance = sum(float(r["distance_px"]) for r in mine)
        assert track["distance_px"] == pytest.approx(distance, abs=0.01 * len(mine))


def test_events_json_and_one_snapshot_per_event(analysed):
    events = json.loads((analysed / "events.json").read_text())["events"]
    assert len(events) == 1
    event = events[0]
    assert {
        "id",
        "start_frame",
        "end_frame",
        "start_time_s",
        "end_time_s",
        "max_area",
        "snapshot",
    } <= set(event)
    assert event["start_frame"] <= 5 and 45 <= event["end_frame"] <= 51
    snapshots = sorted((analysed / "snapshots").iterdir())
    assert [p.name for p in snapshots] == [Path(event["snapshot"]).name]
    picture = cv2.imread(str(analysed / event["snapshot"]))
    assert picture.shape == (240, 320, 3)
    assert (analysed / "differences" / snapshots[0].name).is_file()


def test_report_json_carries_settings_stats_timings_and_rates(analysed):
    report = json.loads((analysed / "report.json").read_text())
    assert report["frames"] == WALKER.frames
    assert report["fps"] == pytest.approx(15.0)
    assert report["size"] == [320, 240]
    assert report["method"] == "adaptive"
    assert report["settings"]["sensitivity_mode"] == "automatic"
    assert len(report["frame_stats"]) == WALKER.frames
    first = report["frame_stats"][0]
    assert 80 < first["grey_mean"] < 140 and first["grey_std"] > 5
    assert report["timings"]["frames_per_s"] > 0
    assert "segment" in report["timings"]["median_stage_ms"]
    objects = report["evaluation"]["objects"]
    assert report["evaluation"]["detection_rate"] == objects["detection_rate"]
    assert objects["detection_rate"] >= 0.95
    assert objects["false_alarm_rate"] <= 0.05


def test_annotated_video_decodes_frame_for_frame_with_red_boxes(analysed):
    frames = list(decode_all(analysed / "annotated.avi"))
    assert len(frames) == WALKER.frames
    assert frames[0].shape == (240, 320, 3)
    middle = frames[25].astype(int)
    red = (middle[..., 2] > 180) & (middle[..., 1] < 80) & (middle[..., 0] < 80)
    assert red.sum() > 50


def test_annotated_mp4_holds_the_same_frames_in_h264(analysed):
    """What a browser plays: H.264 in MP4, the frames of annotated.avi at the input's rate."""
    avi = list(decode_all(analysed / "annotated.avi"))
    with av.open(str(analysed / "annotated.mp4")) as container:
        stream = container.streams.video[0]
        assert stream.codec_context.name == "h264"
        decoded = list(container.decode(stream))
        length_s = container.duration / 1e6
    mp4 = [f.to_ndarray(format="bgr24") for f in decoded]
    times = [float(f.pts * f.time_base) for f in decoded]
    assert len(mp4) == len(avi) == WALKER.frames
    assert np.allclose(times, np.arange(WALKER.frames) / WALKER.fps, atol=1e-3)
    assert length_s == pytest.approx(WALKER.frames / WALKER.fps, abs=0.01)
    for index in (0, 25, WALKER.frames - 1):
        assert np.abs(mp4[index].astype(int) - avi[index].astype(int)).mean() < 4, index


def test_masks_are_zero_based_binary_and_full_size(analysed):
    masks = sorted((analysed / "masks").iterdir())
    assert [p.name for p in masks[:2]] == ["000000.png", "000001.png"]
    assert len(masks) == WALKER.frames
    mask = cv2.imread(str(masks[25]), cv2.IMREAD_GRAYSCALE)
    assert mask.shape == (240, 320)
    assert set(np.unique(mask)) == {0, 255}
    (box,) = [t.box for t in WALKER.truth(25)]
    assert mask[box.y + box.h // 2, box.x + box.w // 2] == 255


def test_report_html_shows_charts_and_rates(analysed):
    html = (analysed / "report.html").read_text()
    assert html.count("data:image/png;base64,") >= 4
    assert "DR" in html and "FAR" in html and "data:image/jpeg;base64," in html


def test_evaluate_rescores_the_folder(analysed, box_truth):
    result = vigil("evaluate", analysed, "--truth", box_truth)
    assert result.returncode == 0, result.stderr
    rates = json.loads(result.stdout)["objects"]
    report = json.loads((analysed / "report.json").read_text())
    assert rates == report["evaluation"]["objects"]


def test_cdnet_style_truth_gives_pixel_metrics(tmp_path, walker_video):
    gt = tmp_path / "seq" / "groundtruth"
    gt.mkdir(parents=True)
    for i in range(WALKER.frames):
        label = np.zeros((240, 320), np.uint8)
        for t in WALKER.truth(i):
            label[t.box.y : t.box.y + t.box.h, t.box.x : t.box.x + t.box.w] = 255
        cv2.imwrite(str(gt / f"gt{i + 1:06d}.png"), label)
    (tmp_path / "seq" / "temporalROI.txt").write_text(f"1 {WALKER.frames}")
    result = vigil(
        "analyze", walker_video, "--out", tmp_path / "out", "--truth", tmp_path / "seq", "--quiet"
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout == ""
    pixels = json.loads((tmp_path / "out" / "report.json").read_text())["evaluation"]["pixels"]
    assert pixels["f_measure"] > 0.8


def _cdnet_sequence(folder: Path, size: tuple[int, int]) -> Path:
    """A CDnet-style sequence: input/in*.jpg, groundtruth/gt*.png (``size``), an ROI."""
    (folder / "input").mkdir(parents=True)
    (folder / "groundtruth").mkdir()
    for i in range(WALKER.frames):
        cv2.imwrite(str(folder / "input" / f"in{i + 1:06d}.jpg"), WALKER.frame(i))
        label = np.zeros((240, 320), np.uint8)
        for t in WALKER.truth(i):
            label[t.box.y : t.box.y + t.box.h, t.box.x : t.box.x + t.box.w] = 255
        cv2.imwrite(str(folder / "groundtruth" / f"gt{i + 1:06d}.png"), cv2.resize(label, size))
    cv2.imwrite(str(folder / "ROI.jpg"), np.full((size[1], size[0]), 255, np.uint8))
    return folder


def test_cdnet_sequence_folder_is_analysed_from_its_input_frames(tmp_path):
    sequence = _cdnet_sequence(tmp_path / "seq", (320, 240))
    result = vigil("analyze", sequence, "--out", tmp_path / "out", "--truth", sequence, "--quiet")
    assert result.returncode == 0, result.stderr
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["frames"] == WALKER.frames  # the frames of input/, not ROI.jpg alone
    assert report["evaluation"]["pixels"]["f_measure"] > 0.8


def test_a_sequence_folder_with_one_label_picture_is_analysed_from_its_input(tmp_path):
    """Wallflower's layout: frames in input/, one hand-labelled frame beside it."""
    folder = tmp_path / "waving-trees"
    (folder / "input").mkdir(parents=True)
    for i in range(WALKER.frames):
        cv2.imwrite(str(folder / "input" / f"b{i:05d}.png"), WALKER.frame(i))
    cv2.imwrite(str(folder / "hand_segmented_00010.png"), np.zeros((240, 320), np.uint8))
    result = vigil("analyze", folder, "--out", tmp_path / "out", "--quiet")
    assert result.returncode == 0, result.stderr
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["frames"] == WALKER.frames
    assert {row["track_id"] for row in read_tracks(tmp_path / "out")} == {"1"}


def test_truth_at_another_scale_is_scored_and_of_another_shape_refused(tmp_path, walker_video):
    doubled = _cdnet_sequence(tmp_path / "doubled", (640, 480))
    result = vigil("analyze", walker_video, "--out", tmp_path / "a", "--truth", doubled, "--quiet")
    assert result.returncode == 0, result.stderr
    evaluation = json.loads((tmp_path / "a" / "report.json").read_text())["evaluation"]
    assert evaluation["pixels"]["f_measure"] > 0.8
    # True boxes in the input's pixels, not the labels': the walker is found.
    assert evaluation["objects"]["detection_rate"] > 0.8
    wide = _cdnet_sequence(tmp_path / "wide", (720, 480))
    result = vigil("analyze", walker_video, "--out", tmp_path / "b", "--truth", wide)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        f"vigil analyze: error: ground-truth labels in {wide} are 720x480, "
        "the input is 320x240: not the same scene"
    ]
    result = vigil("evaluate", tmp_path / "a", "--truth", wide)
    assert result.returncode == 2 and "not the same scene" in result.stderr


def test_truth_of_frames_the_input_lacks_is_warned_of(tmp_path, walker_video):
    truth = tmp_path / "late.json"
    truth.write_text(json.dumps({"frames": {"5000": [[10, 10, 30, 40]]}}))
    result = vigil("analyze", walker_video, "--out", tmp_path / "out", "--truth", truth, "--quiet")
    assert result.returncode == 0
    assert "no frame of the input has ground truth" in result.stderr
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["evaluation"]["frames_scored"] == 0


@pytest.mark.parametrize("name", ["img{:04d}.png", "{}.png", "frame-{}.jpg"])
def test_folder_of_frames_sorted_by_name(tmp_path, name):
    # Numbers in names count by their value: 2.png comes before 10.png.
    folder = tmp_path / "frames"
    folder.mkdir()
    for i in range(40):
        cv2.imwrite(str(folder / name.format(i)), WALKER.frame(i))
    result = vigil("analyze", folder, "--out", tmp_path / "out", "--fps", "15", "--quiet")
    assert result.returncode == 0, result.stderr
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["frames"] == 40 and report["fps"] == 15
    assert report["tracks"][0]["mean_speed_px_s"] == pytest.approx(60.0, rel=0.05)


def test_calibrated_camera_gives_metres_and_km_h(tmp_path, walker_video):
    # Straight down from 10 m, 90 degree field of view over 240 rows: 0.0833 m per pixel,
    # so 60 px/s is 5 m/s = 18 km/h.
    calibration = tmp_path / "camera.json"
    calibration.write_text(
        json.dumps({"camera_height_m": 10, "tilt_deg": 90, "vertical_fov_deg": 90})
    )
    result = vigil(
        "analyze", walker_video, "--out", tmp_path / "out", "--calibration", calibration, "--quiet"
    )
    assert result.returncode == 0, result.stderr
    (track,) = json.loads((tmp_path / "out" / "report.json").read_text())["tracks"]
    assert track["mean_speed_km_h"] == pytest.approx(18.0, rel=0.06)


def _missing(d: Path) -> Path:
    return d / "missing.avi"


def _empty(d: Path) -> Path:
    (d / "empty.avi").write_bytes(b"")
    return d / "empty.avi"


def _text(d: Path) -> Path:
    (d / "text.avi").write_text("hello, not a video\n" * 50)
    return d / "text.avi"


def _empty_folder(d: Path) -> Path:
    (d / "noframes").mkdir()
    return d / "noframes"


def _picture(d: Path) -> Path:
    cv2.imwrite(str(d / "still.png"), WALKER.frame(10))
    return (d / "still.png").rename(d / "still.avi")


def _one_frame_folder(d: Path) -> Path:
    (d / "one").mkdir()
    cv2.imwrite(str(d / "one" / "000001.png"), WALKER.frame(10))
    return d / "one"


def _cut_mp4(d: Path) -> Path:
    """An MP4 cut before its index (moov), which FFmpeg itself complains of on stderr."""
    whole = write_scene_video(WALKER, d / "whole.mp4", fourcc="mp4v").read_bytes()
    (d / "cut.mp4").write_bytes(whole[: len(whole) // 2])
    return d / "cut.mp4"


@pytest.mark.parametrize(
    ("make", "reason"),
    [
        (_missing, "not found"),
        (_empty, "empty"),
        (_text, "not a video"),
        (_empty_folder, "no image frames"),
        (_picture, "only one decodable frame"),
        (_one_frame_folder, "holds only one image"),
        (_cut_mp4, "not a video FFmpeg can decode"),
    ],
    ids=["missing", "empty", "not-a-video", "empty-folder", "picture", "one-frame", "cut-mp4"],
)
def test_bad_input_exits_2_with_one_readable_line(tmp_path, make, reason):
    result = vigil("analyze", make(tmp_path), "--out", tmp_path / "out")
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert reason in lines[0] and "Traceback" not in result.stderr


def test_bad_truth_and_bad_options_exit_2(tmp_path, walker_video):
    bad = tmp_path / "truth.json"
    bad.write_text('{"frames": {"0": [[1, 2, 3]]}}')
    result = vigil("analyze", walker_video, "--out", tmp_path / "o", "--truth", bad)
    assert result.returncode == 2 and "box" in result.stderr
    result = vigil("analyze", walker_video, "--sensitivity", "900")
    assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1
    result = vigil("analyze", walker_video, "--method", "magic")
    assert result.returncode == 2 and "invalid choice" in result.stderr


def test_sensitivity_changes_what_is_detected(tmp_path, walker_video):
    counts = {}
    for sensitivity in ("8", "200"):
        out = tmp_path / sensitivity
        result = vigil(
            "analyze", walker_video, "--out", out, "--sensitivity", sensitivity, "--quiet"
        )
        assert result.returncode == 0, result.stderr
        counts[sensitivity] = len(read_tracks(out))
    assert counts["8"] > 20 and counts["200"] == 0


def test_a_second_analysis_into_the_same_folder_leaves_none_of_the_first(
    tmp_path, walker_video, box_truth
):
    out = tmp_path / "out"
    assert vigil("analyze", walker_video, "--out", out, "--masks", "--quiet").returncode == 0
    assert vigil("evaluate", out, "--truth", box_truth).returncode == 0
    first = json.loads((out / "events.json").read_text())["events"]
    assert first and list((out / "snapshots").glob("*.jpg")) and (out / "evaluation.json").exists()
    (out / "snapshots" / "mine.jpg").write_bytes(b"the user's own")
    (out / "notes.txt").write_text("the user's own")

    # Nothing passes this sensitivity: no event, no snapshot, and no masks asked for.
    result = vigil("analyze", walker_video, "--out", out, "--sensitivity", "200", "--quiet")
    assert result.returncode == 0, result.stderr
    assert json.loads((out / "events.json").read_text())["events"] == []
    assert sorted(p.name for p in (out / "snapshots").iterdir()) == ["mine.jpg"]
    assert not list((out / "differences").iterdir())
    assert not (out / "masks").exists(), "masks of the first run, scored by vigil evaluate"
    assert not (out / "evaluation.json").exists(), "the first run's scores"
    assert (out / "notes.txt").read_text() == "the user's own"


def test_an_empty_path_or_a_file_for_the_output_folder_exits_2(tmp_path, walker_video):
    # An empty path is the current folder to Path: the outputs would land among its files.
    for args in (("", "--out", tmp_path / "o"), (walker_video, "--out", "")):
        result = vigil("analyze", *args, "--quiet", cwd=tmp_path)
        assert result.returncode == 2 and "an empty path" in result.stderr, result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == [], "it wrote into the current folder"
    (tmp_path / "afile").write_text("mine")
    result = vigil("analyze", walker_video, "--out", tmp_path / "afile", "--quiet")
    assert result.returncode == 2
    assert result.stderr.strip().endswith(f"the output folder is a file: {tmp_path / 'afile'}")
    assert (tmp_path / "afile").read_text() == "mine"


@pytest.mark.parametrize(("size", "fps"), [((1280, 720), 30.0), ((640, 480), 25.0)])
def test_a_walker_s_largest_speed_is_its_own_not_its_entry_s(tmp_path, size, fps):
    # Coming in at the frame's edge, a step of one pixel at detection size in a fit of
    # two sightings gave 1.6 to 2.1 times the walker's speed as its largest.
    walker = MovingObject((-40, size[1] // 3), (150.0, 0.0), (40, 90), 60)
    scene = Scene("entry", size=size, fps=fps, frames=int(3 * fps), objects=(walker,))
    video = write_scene_video(scene, tmp_path / "entry.avi")
    report = analyze(video, tmp_path / "out", AnalysisOptions())
    track = max(report["tracks"], key=lambda t: t["frames"])
    assert track["max_speed_px_s"] <= 1.25 * 150.0, track


def test_a_min_area_too_small_at_the_detection_size_is_warned_of_with_the_width_to_use(
    tmp_path,
):
    # 12x12 objects in 1080p are 2x2 pixels at 320 wide: found in half the frames,
    # boxed at 24x24, and nothing said why.
    scene = Scene("tiny", size=(1920, 1080), fps=25.0, frames=5)
    video = write_scene_video(scene, tmp_path / "tiny.avi")
    result = vigil("analyze", video, "--out", tmp_path / "out", "--quiet")
    assert result.returncode == 0, result.stderr
    (line,) = result.stderr.splitlines()
    assert "1.7 px across at the detection size (320 of 1920 px wide)" in line, line
    assert "a detection width of 768 (or a min area of 576 px or more) keeps them" in line
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["warnings"] == [line.removeprefix("vigil analyze: warning: ")]
    wide = vigil("analyze", video, "--out", tmp_path / "wide", "--detect-width", "768", "--quiet")
    assert wide.returncode == 0 and wide.stderr == ""
