"""Decoding ahead: a file's next frames are read by a thread of their own while the
current one is analysed.

OpenCV lets go of the GIL while it reads and decodes, so on a machine with a core to
spare a job takes about as long as the slower of decoding and analysing, not their sum
(``bench/bench_pipeline.py``'s "with decode" rows run this path, as ``vigil analyze``
does). At most ``depth`` frames wait, so memory stays bounded whatever the file.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator
from typing import TypeVar

T = TypeVar("T")

PUT_TIMEOUT_S = 0.1
"""How often a reader waiting for room looks whether its consumer has gone."""


class _End:
    """What the reader puts last: the error the source raised, if any."""

    def __init__(self, error: BaseException | None = None) -> None:
        self.error = error


def read_ahead(items: Iterator[T], depth: int) -> Iterator[T]:
    """``items`` in order, produced up to ``depth`` ahead by a thread; an error the source
    raises is raised here, where it would have been. Closing this generator early (or
    dropping it) stops the thread and closes ``items`` from it."""
    waiting: queue.Queue[T | _End] = queue.Queue(maxsize=depth)
    stopped = threading.Event()

    def offer(item: T | _End) -> bool:
        while not stopped.is_set():
            try:
                waiting.put(item, timeout=PUT_TIMEOUT_S)
                return True
            except queue.Full:
                continue
        return False

    def read() -> None:
        try:
            for item in items:
                if not offer(item):
                    return
            offer(_End())
        except BaseException as error:  # Handed to the consumer, raised there.
            offer(_End(error))
        finally:
            close = getattr(items, "close", None)
            if close is not None:
                close()  # From this thread, the one that ran the source.

    reader = threading.Thread(target=read, name="read-ahead", daemon=True)
    reader.start()
    try:
        while True:
            item = waiting.get()
            if isinstance(item, _End):
                if item.error is not None:
                    raise item.error
                return
            yield item
    finally:
        stopped.set()
        reader.join()
