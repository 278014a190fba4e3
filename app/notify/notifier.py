"""The notifier: an event's start goes to every notification target, each in its own thread.

It listens to the server's event bus (``follow``, on the server's event loop, as a /ws
client does) and reacts to ``alarm`` messages; the camera workers know nothing of it.
Per alarm it only decides, for each target, whether to send (the target's cameras, and
``VIGIL_NOTIFY_GAP_S``: at most one message per event and target in that time), and
hands the alarm to the target's worker: a thread with a bounded queue. The worker reads
the snapshot, composes the message and sends it through Apprise, with a timeout per
attempt, retrying a failure ``VIGIL_NOTIFY_RETRIES`` times with a doubling wait. So a
target that hangs or refuses holds up only its own queue: never detection, /ws or
another target. When its queue is full the oldest message waiting is dropped.

Each target counts its messages sent and failed (given up after every attempt, or
dropped), keeps its last error and when, and logs once when it starts failing and once
when it works again, not once per attempt. ``counters()`` gives the counts, for metrics.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import re
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.core.config import Settings
from app.events.messages import Wire
from app.notify.message import alarm_body, alarm_title, sample_body
from app.notify.targets import Destination, Message, Outcome, TargetError, quiet_apprise
from app.sources.live import MASK
from app.storage.db import IntegrityError

if TYPE_CHECKING:
    from app.storage.db import Database
    from app.storage.files import SnapshotStore
    from app.workers.bus import Subscriber

log = logging.getLogger("vigil.notify")

QUEUE_SIZE = 20
"""Messages waiting per target; beyond, the oldest is dropped (and counted as failed)."""
MAX_RETRY_WAIT_S = 60.0
"""The longest wait between two attempts at one message."""
EVENTS_REMEMBERED = 1000
"""Events whose last message time a target keeps for the gap (an event's ``motion_end``
forgets it; this bounds what a lost one leaves)."""
STOP_WAIT_S = 1.0
"""How long stopping waits for each worker: one in the middle of a send is left to end
on its own (a daemon thread, done within ``VIGIL_NOTIFY_TIMEOUT_S``)."""
TEST_TITLE = "Vigil: test message"


class DuplicateTargetError(ValueError):
    """A target with this URL is there already."""


class FixedTargetError(ValueError):
    """The target comes from ``VIGIL_NOTIFY_URLS``: it is changed there, not by the API."""


@dataclass(frozen=True)
class Job:
    alarm: Wire
    started: float | None
    """When the alarm's event began, for a later alarm of it; None for its first."""


Compose = Callable[[Job], Message]


class TargetWorker:
    """One target: its settings, its queue and thread, its counts and last error."""

    def __init__(
        self,
        row: dict[str, Any],
        destination: Destination | None,
        compose: Compose,
        settings: Settings,
        broken: str | None = None,
    ) -> None:
        self.id: int = row["id"]
        self.url: str = row["url"]
        self.cameras: list[int] | None = row["cameras"]
        self.origin: str = row["origin"]
        self.created_at: float = row["created_at"]
        self.destination = destination
        self.shown = destination.shown if destination else _scheme_only(self.url)
        self.service = destination.service if destination else "unknown"
        self._compose = compose
        self._timeout_s = settings.notify_timeout_s
        self._retries = settings.notify_retries
        self._retry_s = settings.notify_retry_s
        self._queue: queue.Queue[Job | None] = queue.Queue(QUEUE_SIZE)
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._last_sent: dict[int, float] = {}  # event id -> ts of its last alarm let through
        self.sent = 0
        self.failed = 0
        self.last_sent_at: float | None = None
        self.last_error: str | None = broken
        self.last_error_at: float | None = time.time() if broken else None
        self.failing_since: float | None = self.last_error_at
        self._lost_in_spell = 0
        self._thread = threading.Thread(target=self._run, name=f"notify-{self.id}", daemon=True)

    def start(self) -> None:
        if self.destination is not None:
            self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._put(None)

    def join(self, timeout: float) -> None:
        if self._thread.is_alive():
            self._thread.join(timeout)

    # Deciding (on the event loop: no I/O, no waiting) -----------------------------------

    def offer(self, alarm: Wire, started: float | None, gap_s: float) -> bool:
        """Queue ``alarm`` if this target takes its camera and the event has had no
        message within ``gap_s``; whether it was queued."""
        if self.destination is None or self._stop.is_set():
            return False
        if self.cameras is not None and alarm["camera_id"] not in self.cameras:
            return False
        event, ts = alarm["event_id"], alarm["ts"]
        last = self._last_sent.get(event)
        if last is not None and ts - last < gap_s:
            return False
        self._last_sent.pop(event, None)
        self._last_sent[event] = ts
        while len(self._last_sent) > EVENTS_REMEMBERED:
            del self._last_sent[next(iter(self._last_sent))]
        if self._put(Job(alarm, started)):
            self._note_dropped()
        return True

    def forget(self, event_id: int) -> None:
        self._last_sent.pop(event_id, None)

    def _put(self, job: Job | None) -> bool:
        """Queue ``job``, dropping the oldest waiting if the queue is full: whether one was."""
        dropped = False
        while True:
            try:
                self._queue.put_nowait(job)
                return dropped
            except queue.Full:
                with contextlib.suppress(queue.Empty):
                    dropped = self._queue.get_nowait() is not None or dropped

    # Sending (in the target's thread) ---------------------------------------------------

    def _run(self) -> None:
        while not self._stop.is_set():
            job = self._queue.get()
            if job is None or self._stop.is_set():
                return
            try:
                message = self._compose(job)
            except Exception:
                log.exception("notifications: target %d: composing a message failed", self.id)
                continue
            self._deliver(message)

    def _deliver(self, message: Message) -> None:
        assert self.destination is not None
        wait = self._retry_s
        for attempt in range(self._retries + 1):
            outcome = self.destination.send(message, self._timeout_s)
            if outcome.ok:
                self._note_sent()
                return
            self._note_error(outcome.error or "not sent", retrying=attempt < self._retries)
            if attempt == self._retries or self._stop.wait(wait):
                break
            wait = min(wait * 2, MAX_RETRY_WAIT_S)
        with self._lock:
            self.failed += 1
            self._lost_in_spell += 1

    def _note_sent(self) -> None:
        with self._lock:
            self.sent += 1
            self.last_sent_at = time.time()
            since, lost = self.failing_since, self._lost_in_spell
            self.failing_since = None
            self._lost_in_spell = 0
        if since is not None:
            log.info(
                "notifications: target %d (%s) works again, after failing since %s"
                " (%d message(s) lost)",
                self.id,
                self.shown,
                time.strftime("%H:%M:%S", time.localtime(since)),
                lost,
            )

    def _note_error(self, error: str, retrying: bool) -> None:
        """An attempt failed: kept as the last error; logged if it starts a spell."""
        now = time.time()
        with self._lock:
            self.last_error, self.last_error_at = error, now
            starts = self.failing_since is None
            if starts:
                self.failing_since = now
        if starts:
            log.warning(
                "notifications: target %d (%s) failing: %s (%s; not logged again until it works)",
                self.id,
                self.shown,
                error,
                "retrying" if retrying else "given up",
            )

    def _note_dropped(self) -> None:
        with self._lock:
            self.failed += 1
            self._lost_in_spell += 1
        self._note_error(
            f"a message dropped: {QUEUE_SIZE} were waiting for the target", retrying=True
        )

    # Showing ----------------------------------------------------------------------------

    def view(self) -> dict[str, Any]:
        """The target as the API shows it: its URL masked, its counts and state."""
        with self._lock:
            return {
                "id": self.id,
                "url": self.shown,
                "service": self.service,
                "cameras": self.cameras,
                "origin": self.origin,
                "created_at": self.created_at,
                "sent": self.sent,
                "failed": self.failed,
                "pending": self._queue.qsize(),
                "last_sent_at": self.last_sent_at,
                "last_error": self.last_error,
                "last_error_at": self.last_error_at,
                "failing": self.failing_since is not None,
            }


class Notifier:
    """Every target, its worker, and what goes to each."""

    def __init__(self, settings: Settings) -> None:
        """Checks ``VIGIL_NOTIFY_URLS``: ValueError naming the first URL Apprise cannot use."""
        quiet_apprise()
        self.settings = settings
        for number, url in enumerate(settings.notify_url_list, start=1):
            try:
                Destination(url)
            except TargetError as exc:
                raise ValueError(f"VIGIL_NOTIFY_URLS, URL {number}: {exc}") from None
        self._workers: dict[int, TargetWorker] = {}
        self._lock = threading.Lock()
        self._changing = threading.Lock()  # Targets added or deleted one change at a time.
        self._starts: dict[int, float] = {}  # event id -> ts of its first alarm heard
        self._db: Database | None = None
        self._snapshots: SnapshotStore | None = None

    @property
    def db(self) -> Database:
        if self._db is None:
            raise RuntimeError("the notifier has not started")
        return self._db

    def start(self, db: Database, snapshots: SnapshotStore) -> None:
        """The targets of ``VIGIL_NOTIFY_URLS`` stored, and every stored target's worker
        started."""
        self._db, self._snapshots = db, snapshots
        added, removed = db.sync_env_targets(self.settings.notify_url_list)
        if added or removed:
            log.info(
                "notifications: VIGIL_NOTIFY_URLS added %d target(s), removed %d", added, removed
            )
        for row in db.targets():
            self._start_worker(row)
        if self._workers:
            shown = ", ".join(w.shown for w in self._workers.values())
            log.info("notifications: %d target(s): %s", len(self._workers), shown)

    def _start_worker(self, row: dict[str, Any]) -> TargetWorker:
        try:
            destination: Destination | None = Destination(row["url"], self.settings.public_url)
            broken = None
        except TargetError as exc:  # Stored by an older Apprise that took it.
            destination, broken = None, f"Apprise cannot use it any more: {exc}"
        worker = TargetWorker(row, destination, self._compose, self.settings, broken)
        with self._lock:
            self._workers[worker.id] = worker
        worker.start()
        return worker

    def follow_targets(self) -> None:
        """Follow the targets in the database: those another node's API added get their
        worker here, those it deleted lose theirs (with several nodes, at each renewal)."""
        with self._changing:
            rows = {row["id"]: row for row in self.db.targets()}
            with self._lock:
                gone = [self._workers.pop(i) for i in set(self._workers) - rows.keys()]
                new = [row for i, row in rows.items() if i not in self._workers]
            for worker in gone:
                worker.stop()
                log.info("notifications: target %d deleted elsewhere: %s", worker.id, worker.shown)
            for row in new:
                worker = self._start_worker(row)
                log.info("notifications: target %d added elsewhere: %s", worker.id, worker.shown)

    def stop(self) -> None:
        with self._lock:
            workers = list(self._workers.values())
        for worker in workers:
            worker.stop()
        deadline = time.monotonic() + STOP_WAIT_S
        for worker in workers:
            worker.join(max(0.0, deadline - time.monotonic()))

    # The bus ----------------------------------------------------------------------------

    async def follow(self, messages: Subscriber) -> None:
        """React to the bus's messages until it closes (``None``): on the event loop."""
        while True:
            message = await messages.get()
            if message is None:
                return
            try:
                self.handle(message)
            except Exception:  # One odd message must not end notifications.
                log.exception("notifications: a %s message not handled", message.get("type"))

    def handle(self, message: Wire) -> None:
        """An ``alarm`` offered to every target; a ``motion_end`` forgets its event. Another
        node's (relayed over MQTT for its pages) are that node's to send."""
        if message.get("node") not in (None, self.settings.node):
            return
        kind = message.get("type")
        if kind == "motion_end":
            event = message["event_id"]
            self._starts.pop(event, None)
            for worker in self._listed():
                worker.forget(event)
        elif kind == "alarm":
            event, ts = message["event_id"], message["ts"]
            first = self._starts.setdefault(event, ts)
            while len(self._starts) > EVENTS_REMEMBERED:
                del self._starts[next(iter(self._starts))]
            started = first if first < ts else None
            for worker in self._listed():
                worker.offer(message, started, self.settings.notify_gap_s)

    def _listed(self) -> list[TargetWorker]:
        with self._lock:
            return list(self._workers.values())

    def _compose(self, job: Job) -> Message:
        """An alarm's message, its snapshot attached if its file is still there."""
        alarm = job.alarm
        public = self.settings.public_url
        return Message(
            title=alarm_title(alarm),
            body=alarm_body(alarm, public, job.started),
            attachment=self._snapshot_file(alarm.get("snapshot_id")),
            attachment_name=f"vigil-{_slug(alarm['camera_name'])}-event{alarm['event_id']}.jpg",
            notify_type="warning",
        )

    def _snapshot_file(self, snapshot_id: int | None) -> Path | None:
        if snapshot_id is None or self._snapshots is None:
            return None
        row = self.db.snapshot(snapshot_id)
        if row is None:
            return None
        try:
            path = self._snapshots.path(row["path"])
        except ValueError:
            return None
        return path if path.is_file() else None

    # The API ----------------------------------------------------------------------------

    def views(self) -> list[dict[str, Any]]:
        return [worker.view() for worker in sorted(self._listed(), key=lambda w: w.id)]

    def view(self, target_id: int) -> dict[str, Any] | None:
        with self._lock:
            worker = self._workers.get(target_id)
        return worker.view() if worker else None

    def add(self, url: str, cameras: Sequence[int] | None) -> dict[str, Any]:
        """A new target: TargetError if Apprise cannot use ``url`` (nothing stored),
        DuplicateTargetError if it is a target already."""
        url = url.strip()
        Destination(url)
        with self._changing:
            try:
                target_id = self.db.add_target(url, cameras)
            except IntegrityError:
                same = next((w for w in self._listed() if w.url == url), None)
                which = f" (target {same.id})" if same else ""
                raise DuplicateTargetError(f"this URL is a target already{which}") from None
            row = self.db.target(target_id)
            assert row is not None
            worker = self._start_worker(row)
        log.info("notifications: target %d added: %s", worker.id, worker.shown)
        return worker.view()

    def remove(self, target_id: int) -> bool:
        """Delete a target; False if there is none. FixedTargetError for one of
        ``VIGIL_NOTIFY_URLS``: it would be back at the next start."""
        with self._changing:
            with self._lock:
                worker = self._workers.get(target_id)
                if worker is not None and worker.origin == "env":
                    raise FixedTargetError(
                        f"target {target_id} is set by VIGIL_NOTIFY_URLS: remove it there"
                    )
                self._workers.pop(target_id, None)
            deleted = self.db.delete_target(target_id)
        if worker is not None:
            worker.stop()
            log.info("notifications: target %d deleted: %s", worker.id, worker.shown)
        return deleted or worker is not None

    def test(self, target_id: int) -> Outcome | None:
        """Send a test message to a target now, past its queue, once (no retry): how it
        went. None if there is no such target. Blocks up to ``VIGIL_NOTIFY_TIMEOUT_S``."""
        with self._lock:
            worker = self._workers.get(target_id)
        if worker is None:
            return None
        try:
            destination = Destination(worker.url, self.settings.public_url)
        except TargetError as exc:
            return Outcome(False, str(exc))
        message = Message(TEST_TITLE, sample_body(self.settings.public_url))
        return destination.send(message, self.settings.notify_timeout_s)

    def counters(self) -> dict[int, dict[str, Any]]:
        """Per target id: its masked URL, service, messages ``sent`` and ``failed`` since
        the server started (for ``vigil_notifications_sent_total`` and ``..._failed_total``)."""
        return {
            view["id"]: {k: view[k] for k in ("url", "service", "sent", "failed")}
            for view in self.views()
        }


def _scheme_only(url: str) -> str:
    return f"{url.partition('://')[0]}://{MASK}"


def _slug(name: str) -> str:
    """A camera's name as part of a file name: letters, digits, ``-`` and ``_``."""
    return re.sub(r"[^A-Za-z0-9_-]+", "-", name).strip("-")[:40] or "camera"
