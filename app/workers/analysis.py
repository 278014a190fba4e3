"""Uploaded videos, analysed one process each, with progress relayed to /ws."""

from __future__ import annotations

import contextlib
import json
import logging
import os
import queue
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import app
from app.storage.db import Database
from app.workers.bus import EventBus

log = logging.getLogger("vigil.analysis")

PACKAGE_ROOT = Path(app.__file__).resolve().parent.parent


class AnalysisManager:
    """A queue of uploads and a few threads, each supervising one child process at a time."""

    def __init__(
        self, db: Database, bus: EventBus, root: Path, workers: int = 1, timeout_s: float = 3600.0
    ) -> None:
        self.db = db
        self.bus = bus
        self.root = root
        self.timeout_s = timeout_s
        self.progress: dict[str, float] = {}
        self._queue: queue.Queue[str | None] = queue.Queue()
        self._children: dict[str, subprocess.Popen[str]] = {}
        self._lock = threading.Lock()
        self._stopping = threading.Event()
        self._threads = [
            threading.Thread(target=self._serve, name=f"analysis-{i}", daemon=True)
            for i in range(workers)
        ]

    def start(self) -> None:
        self.root.mkdir(parents=True, exist_ok=True)
        failed = self.db.fail_unfinished_analyses("the server stopped before it finished")
        if failed:
            log.warning("%d analyses were cut short by a restart", failed)
        for thread in self._threads:
            thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        self._stopping.set()
        for _ in self._threads:
            self._queue.put(None)
        with self._lock:
            children = list(self._children.values())
        for child in children:
            with contextlib.suppress(OSError):
                child.kill()
        deadline = time.monotonic() + timeout
        for thread in self._threads:
            thread.join(max(0.0, deadline - time.monotonic()))

    def folder(self, analysis_id: str) -> Path:
        return self.root / analysis_id

    def submit(self, analysis_id: str) -> None:
        self._queue.put(analysis_id)

    def _serve(self) -> None:
        while not self._stopping.is_set():
            analysis_id = self._queue.get()
            if analysis_id is None:
                return
            try:
                self._run(analysis_id)
            except Exception as exc:
                log.exception("analysis %s failed", analysis_id)
                self._finish(analysis_id, "failed", f"analysis failed: {exc}")

    def _run(self, analysis_id: str) -> None:
        row = self.db.analysis(analysis_id)
        if row is None:
            return
        folder = self.folder(analysis_id)
        inputs = sorted(folder.glob("input.*")) or sorted(folder.glob("input"))
        if not inputs:
            self._finish(analysis_id, "failed", "the uploaded file is missing")
            return
        self.db.update_analysis(analysis_id, status="running", progress=0.0)
        self.progress[analysis_id] = 0.0
        self.bus.publish({"type": "status", "analysis_id": analysis_id, "status": "running"})
        self.bus.publish({"type": "progress", "analysis_id": analysis_id, "progress": 0.0})
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(
            p for p in (str(PACKAGE_ROOT), env.get("PYTHONPATH", "")) if p
        )
        command = self.command(inputs[0], folder / "out", row["options"])
        child = subprocess.Popen(
            command,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
            cwd=str(PACKAGE_ROOT),
        )
        with self._lock:
            self._children[analysis_id] = child
        stderr_tail: list[str] = []
        drain = threading.Thread(target=_tail, args=(child.stderr, stderr_tail), daemon=True)
        drain.start()
        error: str | None = None
        done = False
        timer = threading.Timer(self.timeout_s, child.kill)
        timer.daemon = True
        timer.start()
        try:
            assert child.stdout is not None
            for line in child.stdout:
                try:
                    message = json.loads(line)
                except ValueError:
                    continue
                if "progress" in message:
                    fraction = float(message["progress"])
                    self.progress[analysis_id] = fraction
                    self.bus.publish(
                        {
                            "type": "progress",
                            "analysis_id": analysis_id,
                            "progress": fraction,
                            "frames": message.get("frames"),
                        }
                    )
                elif "error" in message:
                    error = str(message["error"])
                elif message.get("done"):
                    done = True
            code = child.wait()
        finally:
            timer.cancel()
            drain.join(1.0)
            with self._lock:
                self._children.pop(analysis_id, None)
        if done and code == 0:
            self.db.update_analysis(analysis_id, progress=1.0)
            self.bus.publish({"type": "progress", "analysis_id": analysis_id, "progress": 1.0})
            self._finish(analysis_id, "done", None)
            return
        if error is None:
            if self._stopping.is_set():
                error = "the server stopped before the analysis finished"
            else:
                last = next((s for s in reversed(stderr_tail) if s.strip()), "")
                error = f"the analysis process crashed (exit status {code})"
                if last:
                    error += f": {last.strip()[:200]}"
        self._finish(analysis_id, "failed", error)

    def command(self, input_path: Path, out_dir: Path, options: dict[str, Any]) -> list[str]:
        """The child process that analyses one upload."""
        return [
            sys.executable,
            "-m",
            "app.workers.analysis_child",
            str(input_path),
            str(out_dir),
            "--options",
            json.dumps(options),
        ]

    def _finish(self, analysis_id: str, status: str, error: str | None) -> None:
        self.progress.pop(analysis_id, None)
        self.db.update_analysis(analysis_id, status=status, error=error, finished_at=time.time())
        self.bus.publish(
            {"type": "status", "analysis_id": analysis_id, "status": status, "error": error}
        )


def _tail(stream: Any, lines: list[str], keep: int = 20) -> None:
    for line in stream:
        lines.append(line)
        del lines[:-keep]
