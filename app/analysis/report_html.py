"""report.html: the analysis as a page a person opens in a browser.

One self-contained file (charts and key frames embedded), drawn with
matplotlib: the tracks over the scene, speed over time, motion area over
time, grey-level mean and deviation per frame, key frames of each event and
the DR/FAR table when ground truth was given.
"""

from __future__ import annotations

import base64
import io
from pathlib import Path
from typing import Any

import cv2
import jinja2
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.figure import Figure

from app.core.atomic import write_atomic

MAX_KEY_FRAMES = 24
MAX_TRACKS_PLOTTED = 40

_TEMPLATES = jinja2.Environment(
    loader=jinja2.FileSystemLoader(Path(__file__).parent / "templates"),
    autoescape=jinja2.select_autoescape(["html"]),
)


def write_report_html(path: Path, report: dict[str, Any], extras: dict[str, Any]) -> None:
    charts = {
        "tracks": _tracks_over_scene(extras.get("first_frame"), extras.get("paths", {})),
        "speed": _speed_over_time(extras.get("speeds", {})),
        "motion": _motion_over_time(report["frame_stats"]),
        "grey": _grey_over_time(report["frame_stats"]),
    }
    key_frames = []
    for key in extras.get("key_frames", [])[:MAX_KEY_FRAMES]:
        image_path = Path(extras["out_dir"]) / key["snapshot"]
        if image_path.is_file():
            key_frames.append({**key, "data": _data_uri(image_path.read_bytes(), "image/jpeg")})
    html = _TEMPLATES.get_template("report.html").render(
        report=report,
        charts=charts,
        key_frames=key_frames,
        evaluation=report.get("evaluation"),
    )
    write_atomic(path, html.encode())


def _tracks_over_scene(first_frame: Any, paths: dict[int, list[tuple[float, float]]]) -> str | None:
    if first_frame is None:
        return None
    fig, ax = _figure(7.0, 7.0 * first_frame.shape[0] / first_frame.shape[1])
    ax.imshow(cv2.cvtColor(first_frame, cv2.COLOR_BGR2RGB))
    for track_id, points in sorted(paths.items())[:MAX_TRACKS_PLOTTED]:
        if not points:
            continue
        xs, ys = zip(*points, strict=True)
        (line,) = ax.plot(xs, ys, linewidth=1.5)
        ax.plot(xs[-1], ys[-1], "o", color=line.get_color(), markersize=4)
        ax.annotate(
            f"#{track_id}", (xs[0], ys[0]), color=line.get_color(), fontsize=8, fontweight="bold"
        )
    ax.set_axis_off()
    return _png(fig)


def _speed_over_time(speeds: dict[int, tuple[list[float], list[float]]]) -> str | None:
    if not speeds:
        return None
    fig, ax = _figure(8.0, 3.2)
    for track_id, (times, values) in sorted(speeds.items())[:MAX_TRACKS_PLOTTED]:
        ax.plot(times, values, linewidth=1.2, label=f"#{track_id}")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("speed (px/s)")
    if len(speeds) <= 12:
        ax.legend(fontsize=7, ncols=4)
    return _png(fig)


def _motion_over_time(stats: list[dict[str, Any]]) -> str | None:
    if not stats:
        return None
    fig, ax = _figure(8.0, 3.0)
    times = [s["time_s"] for s in stats]
    ax.fill_between(
        times, [s["motion_area"] for s in stats], color="#d62728", alpha=0.6, step="mid"
    )
    ax.set_xlabel("time (s)")
    ax.set_ylabel("moving area (px)")
    twin = ax.twinx()
    twin.plot(times, [s["objects"] for s in stats], color="#333333", linewidth=0.8)
    twin.set_ylabel("objects")
    return _png(fig)


def _grey_over_time(stats: list[dict[str, Any]]) -> str | None:
    if not stats:
        return None
    fig, ax = _figure(8.0, 3.0)
    times = [s["time_s"] for s in stats]
    ax.plot(times, [s["grey_mean"] for s in stats], label="mean", color="#1f77b4")
    ax.plot(times, [s["grey_std"] for s in stats], label="standard deviation", color="#ff7f0e")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("grey level")
    ax.legend(fontsize=8)
    return _png(fig)


def _figure(width: float, height: float) -> tuple[Figure, Any]:
    fig, ax = plt.subplots(figsize=(width, max(height, 2.0)), dpi=100)
    return fig, ax


def _png(fig: Figure) -> str:
    buffer = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buffer, format="png")
    plt.close(fig)
    return _data_uri(buffer.getvalue(), "image/png")


def _data_uri(data: bytes, mime: str) -> str:
    return f"data:{mime};base64,{base64.b64encode(data).decode()}"
