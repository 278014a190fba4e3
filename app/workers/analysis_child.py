"""The separate process that analyses one upload (``python -m app.workers.analysis_child``).

A decoder that crashes on a malformed file takes only this process down. It
talks to the server on stdout, one JSON object a line: ``{"progress": 0.42}``
as frames are done, then ``{"done": true}`` or ``{"error": "one line"}``. While
it runs it keeps ``live.jpg`` in the output folder, the latest annotated frame,
for the analysis' MJPEG stream.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

LIVE_FRAME = "live.jpg"
LIVE_INTERVAL_S = 0.1


def _say(message: dict[str, Any]) -> None:
    sys.stdout.write(json.dumps(message) + "\n")
    sys.stdout.flush()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="analysis_child")
    parser.add_argument("input", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--options", default="{}", help="JSON: method, sensitivity, min_area")
    args = parser.parse_args(argv)
    options: dict[str, Any] = json.loads(args.options)
    try:
        import cv2

        from app.analysis import runner
        from app.core.atomic import write_atomic
        from app.vision.pipeline import PipelineConfig

        config = PipelineConfig(
            method=options.get("method") or PipelineConfig.method,
            sensitivity=options.get("sensitivity"),
            min_area=float(options.get("min_area") or PipelineConfig.min_area),
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

        runner.analyze(
            args.input, out_dir, runner.AnalysisOptions(pipeline=config), progress, keep_live_frame
        )
    except ValueError as exc:  # InputError, TruthError, bad options: one readable line.
        _say({"error": str(exc).splitlines()[0] if str(exc) else type(exc).__name__})
        return 2
    except Exception as exc:
        _say({"error": f"analysis failed: {type(exc).__name__}: {exc}".splitlines()[0]})
        return 1
    _say({"done": True})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
