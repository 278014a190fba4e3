"""Uploaded videos, analysed one process each, with progress relayed to /ws."""

from __future__ import annotations

import contextlib
import json
import logging
import os
import queue
import signal
import subprocess  # nosec B404  # only to run this package's own child: argument list, no shell
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import app
from app.events.messages import AnalysisState, AnalysisStatus, Progress
from app.storage.db import Database
from app.workers.bus import EventBus

log = logging.getLogger("vigil.analysis")

PACKAGE_ROOT = Path(app.__file__).resolve().parent.parent
CRASH_SIGNALS = {signal.SIGSEGV, signal.SIGBUS, signal.SIGABRT, signal.SIGILL, signal.SIGFPE}
"""How native code dies on a malformed file (bad read, heap corruption), not how it is stopped."""


@dataclass(frozen=True)
class AnalysisLimits:
    """What one upload's process may take: frame size and address space (None = no limit)."""

    max_pixels: int | None = None
    memory_mb: int | None = None


class AnalysisManager:
    """A queue of uploads and a few threads, each supervising one child process at a time."""

    def __init__(
        self,
        db: Database,
        bus: EventBus,
        root: Path,
        workers: int = 1,
        timeout_s: float = 3600.0,
        limits: AnalysisLimits | None = None,
    ) -> None:
        self.db = db
        self.bus = bus
        self.root = root
        self.timeout_s = timeout_s
        self.limits = limits or AnalysisLimits()
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
        self.bus.publish(AnalysisStatus(analysis_id=analysis_id, status="running"))
        self.bus.publish(Progress(analysis_id=analysis_id, progress=0.0))
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(
            p for p in (str(PACKAGE_ROOT), env.get("PYTHONPATH", "")) if p
        )
        # The child's own options: it names the upload in its errors by the user's file name,
        # not by the path on this server.
        options = {
            **row["options"],
            "name": row["filename"],
            "max_pixels": self.limits.max_pixels,
            "memory_mb": self.limits.memory_mb,
        }
        command = self.command(inputs[0], folder / "out", options)
        child = subprocess.Popen(  # nosec B603  # sys.executable and our module; no shell
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
        warnings: list[str] = []
        done = False
        timed_out = threading.Event()

        def time_out() -> None:
            timed_out.set()
            child.kill()

        timer = threading.Timer(self.timeout_s, time_out)
        timer.daemon = True
        timer.start()
        try:
            assert child.stdout is not None
            for line in child.stdout:
                try:
                    message = json.loads(line)
                except ValueError:
                    continue
                if not isinstance(message, dict):  # A native library's stray output.
                    continue
                if "progress" in message:
                    fraction = float(message["progress"])
                    self.progress[analysis_id] = fraction
                    self.bus.publish(
                        Progress(
                            analysis_id=analysis_id,
                            progress=fraction,
                            frames=message.get("frames"),
                        )
                    )
                elif "error" in message:
                    error = _one_line(str(message["error"])) or "the analysis failed"
                elif "warning" in message:
                    warnings.append(_one_line(str(message["warning"])))
                    log.warning("analysis %s: %s", analysis_id, warnings[-1])
                elif message.get("done"):
                    done = True
            code = child.wait()
        finally:
            timer.cancel()
            drain.join(1.0)
            with self._lock:
                self._children.pop(analysis_id, None)
        if done and code == 0:
            self.progress[analysis_id] = 1.0
            self.bus.publish(Progress(analysis_id=analysis_id, progress=1.0))
            # The warnings are also the report's (GET /api/analyses/{id}: report.warnings).
            self._finish(analysis_id, "done", None, warnings)
            return
        if error is None:
            if self._stopping.is_set():
                error = "the server stopped before the analysis finished"
            elif timed_out.is_set():
                error = f"the analysis took longer than {self.timeout_s:g} s and was stopped"
            else:
                error = exit_reason(code, next((s for s in reversed(stderr_tail) if s.strip()), ""))
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

    def _finish(
        self,
        analysis_id: str,
        status: AnalysisState,
        error: str | None,
        warnings: list[str] | None = None,
    ) -> None:
        # A failed analysis keeps how far it got; the row first, so that no reader sees
        # the analysis running at the progress stored when it started.
        reached = self.progress.get(analysis_id, 0.0)
        self.db.update_analysis(
            analysis_id, status=status, error=error, finished_at=time.time(), progress=reached
        )
        self.progress.pop(analysis_id, None)
        some: dict[str, Any] = {"warnings": warnings} if warnings else {}  # Only when any.
        self.bus.publish(
            AnalysisStatus(analysis_id=analysis_id, status=status, error=error, **some)
        )


def exit_reason(code: int, last_stderr: str = "") -> str:
    """One line saying how a child that sent no error of its own ended."""
    detail = f": {_one_line(last_stderr, 200)}" if last_stderr.strip() else ""
    if code >= 0:
        return f"the analysis process failed (exit status {code}){detail}"
    sig = _signal(code)
    named = signal_label(code)
    if sig in CRASH_SIGNALS:
        return f"the decoder crashed ({named}) on this file{detail}"
    if sig == signal.SIGKILL:
        return f"the analysis process was killed ({named}), perhaps for using too much memory"
    return f"the analysis process was stopped ({named})"


def signal_label(code: int) -> str:
    """``signal 11, SIGSEGV`` for a process whose exit code is -11."""
    sig = _signal(code)
    return f"signal {-code}, {sig.name}" if sig else f"signal {-code}"


def _signal(code: int) -> signal.Signals | None:
    try:
        return signal.Signals(-code)
    except ValueError:
        return None


def _one_line(text: str, limit: int = 300) -> str:
    first = text.strip().splitlines()[0] if text.strip() else ""
    return first[:limit]


def _tail(stream: Any, lines: list[str], keep: int = 20) -> None:
    for line in stream:
        lines.append(line)
        del lines[:-keep]
