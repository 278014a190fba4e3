"""Thread-safe fan-out of /ws messages (alarms, status, progress) to WebSocket clients.

Workers publish a message's model (``app.events.messages``) from their own threads; the
bus turns it into its wire form once, and each subscriber, an asyncio queue on the
server's event loop fed through ``call_soon_threadsafe``, gets that dict. A slow client
loses its oldest messages, never blocks a worker.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
from typing import Protocol

from app.events.messages import Wire, WsMessage


class Publisher(Protocol):
    """Where a worker sends its messages: the bus, or the pipe of a camera process."""

    def publish(self, message: WsMessage) -> None: ...


Subscriber = asyncio.Queue[Wire | None]


class EventBus:
    def __init__(self, queue_size: int = 256) -> None:
        self.queue_size = queue_size
        self._lock = threading.Lock()
        self._subscribers: set[tuple[asyncio.AbstractEventLoop, Subscriber]] = set()
        self._closed = False

    def subscribe(self) -> Subscriber:
        queue: Subscriber = asyncio.Queue(self.queue_size)
        with self._lock:
            if self._closed:
                queue.put_nowait(None)
            self._subscribers.add((asyncio.get_running_loop(), queue))
        return queue

    def unsubscribe(self, queue: Subscriber) -> None:
        with self._lock:
            self._subscribers = {s for s in self._subscribers if s[1] is not queue}

    def publish(self, message: WsMessage | Wire) -> None:
        """Send ``message`` to every subscriber, in its wire form. A dict is one already: a
        message that a camera process made from its model and sent over its pipe."""
        if isinstance(message, WsMessage):
            message = message.wire()
        with self._lock:
            subscribers = list(self._subscribers)
        for loop, queue in subscribers:
            with contextlib.suppress(RuntimeError):  # The loop is closed: nobody listens.
                loop.call_soon_threadsafe(_put, queue, message)

    def close(self) -> None:
        """Tell every subscriber to finish (server shutdown)."""
        with self._lock:
            self._closed = True
            subscribers = list(self._subscribers)
        for loop, queue in subscribers:
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(_put, queue, None)


def _put(queue: Subscriber, message: Wire | None) -> None:
    while True:
        try:
            queue.put_nowait(message)
            return
        except asyncio.QueueFull:
            with contextlib.suppress(asyncio.QueueEmpty):
                queue.get_nowait()
