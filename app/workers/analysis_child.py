"""The separate process that analyses one upload (``python -m app.workers.analysis_child``).

A decoder that crashes on a malformed file takes only this process down. It
talks to the server on stdout, one JSON object a line: ``{"progress": 0.42}``
as frames are done, ``{"warning": "one line"}`` for each way the upload was not read
whole (frames that did not decode and were skipped, a file that ended early; also in
report.json's ``warnings``), then ``{"done": true}`` or ``{"error": "one line"}``. While
it runs it keeps ``live.jpg`` in the output folder, the latest annotated frame,
for the analysis' MJPEG stream.

``--options`` also carries the upload's own file name (``name``, used in errors
instead of the path on the server), ``max_pixels`` (largest frame allowed,
checked from the header before a frame is decoded) and ``memory_mb`` (this
process' address space, so a decoder that allocates without bound fails here).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import time
from pathlib import Path
from typing import Any

LIVE_FRAME = "live.jpg"
LIVE_INTERVAL_S = 0.1


def _limit_memory(memory_mb: int) -> None:
    _, hard = resource.getrlimit(resource.RLIMIT_AS)
    soft = memory_mb * 1024 * 1024
    if hard != resource.RLIM_INFINITY:
        soft = min(soft, hard)
    resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def _out_of_memory(exc: BaseException) -> bool:
    if isinstance(exc, MemoryError):
        return True
    text = str(exc)
    return "Insufficient memory" in text or "Failed to allocate" in text


def _say(message: dict[str, Any]) -> None:
    sys.stdout.write(json.dumps(message) + "\n")
    sys.stdout.flush()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="analysis_child")
    parser.add_argument("input", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument(
        "--options",
        default="{}",
        help="JSON: method, sensitivity, min_area, detect_width, name, max_pixels, memory_mb",
    )
    args = parser.parse_args(argv)
    input_path: Path = args.input
    options: dict[str, Any] = {}
    name = input_path.name

    def public(text: str) -> str:
        """One line, naming the upload as its owner knows it, not by its path here."""
        first = text.strip().splitlines()[0] if text.strip() else ""
        return first.replace(str(input_path), name).replace(str(input_path.parent) + "/", "")

    try:
        options = json.loads(args.options)
        name = str(options.get("name") or name)
        if options.get("memory_mb"):
            _limit_memory(int(options["memory_mb"]))
        import cv2

        from app.analysis import runner
        from app.core.atomic import write_atomic
        from app.sources.files import FFMPEG_LOG_QUIET
        from app.vision.pipeline import PipelineConfig

        # Stdout is this process's message channel, and OpenCV prints FFmpeg's messages
        # there when they are enabled: they stay off here, whatever the server's setting.
        os.environ["OPENCV_FFMPEG_LOGLEVEL"] = FFMPEG_LOG_QUIET

        def given(name: str) -> Any:
            value = options.get(name)
            return getattr(PipelineConfig, name) if value is None else value

        config = PipelineConfig(
            method=options.get("method") or PipelineConfig.method,
            sensitivity=options.get("sensitivity"),
            min_area=float(given("min_area")),  # 0 too: no minimum.
            detect_width=int(given("detect_width")),
        )
        out_dir: Path = args.out
        out_dir.mkdir(parents=True, exist_ok=True)
        live_path = out_dir / LIVE_FRAME

        last_live = [0.0]

        def keep_live_frame(frame: Any) -> None:
            """Leave the newest annotated frame for the analysis' live stream."""
            now = time.monotonic()
            if now - last_live[0] >= LIVE_INTERVAL_S:
                last_live[0] = now
                ok, data = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, 75])
                if ok:
                    write_atomic(live_path, data.tobytes())

        last_sent = [0.0]

        def progress(done: int, expected: int | None) -> None:
            now = time.monotonic()
            if now - last_sent[0] < 0.2:
                return
            last_sent[0] = now
            # The header's count may lie, and an unknown length creeps towards 1:
            # either way, never past 0.99 before the analysis ends.
            fraction = min(0.99, done / (expected or done + 300))
            _say({"progress": round(fraction, 4), "frames": done})

        # What is too large is refused from its header, before a frame is decoded.
        analysis = runner.AnalysisOptions(
            pipeline=config, max_pixels=options.get("max_pixels"), input_name=name
        )
        report = runner.analyze(input_path, out_dir, analysis, progress, keep_live_frame)
        for warning in report.get("warnings", []):
            _say({"warning": public(str(warning))})
    except Exception as exc:
        if _out_of_memory(exc):
            limit = options.get("memory_mb")
            _say({"error": f"{name} needs more memory than an analysis may use ({limit} MB)"})
            return 1
        if isinstance(exc, ValueError):  # InputError, TruthError, bad options: one line.
            _say({"error": public(str(exc)) or type(exc).__name__})
            return 2
        _say({"error": public(f"analysis failed: {type(exc).__name__}: {exc}")})
        return 1
    _say({"done": True})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
