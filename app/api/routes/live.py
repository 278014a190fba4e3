"""``WS /ws/live``: the pictures of the cameras a page shows, with what was found as data.

The client says which cameras it shows and how wide, ``{"type": "watch", "cameras":
[1, 2], "width": 640}``, and again whenever that changes (``"cameras": []`` to watch
none). The server sends one binary message per frame and camera
(``app.workers.live_frames``: a 4-byte big-endian header length, a JSON header, the
JPEG), made once in the camera process for every client.

Backpressure: per client, each camera has one slot that holds its newest message; a
new frame replaces what waits there. The client's one sending task takes the slots
and sends them, waiting while the connection's buffer is full. So a slow client gets
fewer frames, never a queue; the cameras and the other clients never wait for it.

Cameras another node of the site runs are relayed from it (``app.nodes.live_relay``):
their messages are that node's, byte for byte, with the same backpressure here.

The session and origin rules are those of ``/ws`` (``app.api.security``'s guards take
every WebSocket). Other message types from the client are ignored; a watch message
that is not one is refused by closing with 1003 and the reason.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import threading
from dataclasses import dataclass

from fastapi import APIRouter, HTTPException, WebSocket, WebSocketDisconnect

from app.api.services import Services, services
from app.nodes.live_relay import NodeFeed
from app.nodes.relay import is_relayed
from app.workers.camera_host import Camera

router = APIRouter()

MAX_CAMERAS = 1024
"""Most cameras one watch message may name."""
MAX_WIDTH = 16384
"""Widest picture a client may ask for (a camera's own JPEG is sent as it is, whatever
its size)."""
RESYNC_S = 1.0
"""How often a client's cameras are looked up again without a watch message: a camera
added since it was named, or replaced (a new source) and so a new hub."""
UNSUPPORTED = 1003


class WatchError(ValueError):
    """A watch message that is not one; its text is the reason the socket closes with."""


@dataclass(frozen=True)
class Watch:
    cameras: tuple[int, ...] = ()
    width: int = 0
    """The widest picture the client shows, in device pixels (0: as the camera has it)."""


def parse_watch(text: str) -> Watch | None:
    """The watch message ``text``; None for a message of another type (ignored)."""
    try:
        message = json.loads(text)
    except ValueError:
        raise WatchError("messages are JSON text") from None
    if not isinstance(message, dict):
        raise WatchError("a message is a JSON object")
    if message.get("type") != "watch":
        return None
    cameras = message.get("cameras")
    if not isinstance(cameras, list) or len(cameras) > MAX_CAMERAS:
        raise WatchError(f"cameras: a list of at most {MAX_CAMERAS} camera ids")
    if not all(type(c) is int for c in cameras):
        raise WatchError("cameras: camera ids are integers")
    width = message.get("width", 0)
    if type(width) is not int or not 0 <= width <= MAX_WIDTH:
        raise WatchError(f"width: an integer from 0 to {MAX_WIDTH}")
    return Watch(tuple(dict.fromkeys(cameras)), width)


class LiveClient:
    """One /ws/live connection's slots: the newest message of each camera, waiting to be
    sent. Hubs offer from the threads that publish; the connection's task takes them.

    Every ``RESYNC_S`` (and when a hub closes) ``resync`` is set and the task woken, to
    look its cameras up again; between, a frame costs the task no lookup and no timer."""

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self._loop = loop
        self._thread = threading.get_ident()
        """The loop's thread (the route runs in it)."""
        self._lock = threading.Lock()
        self._slots: dict[int, bytes] = {}
        self._event = asyncio.Event()
        self._woken = False
        self.resync = True
        self._ticker = loop.call_later(RESYNC_S, self._tick)

    def _tick(self) -> None:
        self.resync = True
        self._event.set()
        self._ticker = self._loop.call_later(RESYNC_S, self._tick)

    def close(self) -> None:
        self._ticker.cancel()

    def offer(self, key: int, message: bytes) -> None:
        with self._lock:
            self._slots[key] = message  # What waited there is dropped: the newest wins.
            if self._woken:
                return  # The task is told already; it takes every slot at once.
            self._woken = True
        if threading.get_ident() == self._thread:  # The loop's own: it reads the frames.
            self._event.set()
            return
        with contextlib.suppress(RuntimeError):  # The loop is closed: nobody listens.
            self._loop.call_soon_threadsafe(self._event.set)

    def wake(self, resync: bool = False) -> None:
        """Wake the task (from any thread); ``resync``: to look its cameras up again."""
        if resync:
            self.resync = True
        with contextlib.suppress(RuntimeError):  # The loop is closed: nobody listens.
            self._loop.call_soon_threadsafe(self._event.set)

    async def take(self) -> dict[int, bytes]:
        """Every slot's message (emptying them), once there is one or something changed."""
        await self._event.wait()
        with self._lock:
            slots, self._slots = self._slots, {}
            self._woken = False
            self._event.clear()
        return slots


class LiveSession:
    """What one connection watches: the hubs its client is registered with, and the nodes
    it is relayed the others from (``app.nodes.live_relay``), kept as its last watch
    message asks."""

    def __init__(self, svc: Services, client: LiveClient, relayed: bool) -> None:
        self.svc = svc
        self.client = client
        self.relayed = relayed
        """A client that is another node: it is sent this node's cameras only."""
        self.wanted = Watch()
        self.watched: dict[int, tuple[Camera, int]] = {}
        """Camera id -> the camera whose hub the client is registered with, and the width."""
        self.feeds: dict[str, NodeFeed] = {}
        """Node -> the feed of the client's cameras that node runs."""
        self.shown: frozenset[int] = frozenset()
        """The cameras whose frames go to the client: here or relayed."""

    def want(self, watch: Watch) -> None:
        self.wanted = watch
        self.sync()

    def sync(self) -> None:
        """Register the client with the hubs of the cameras wanted that run here, and with
        no other; follow those that run on other nodes from there."""
        wanted = set(self.wanted.cameras)
        width = self.wanted.width
        for camera_id, (camera, _) in list(self.watched.items()):
            current = self.svc.cameras.get(camera_id)
            if camera_id not in wanted or current is not camera or camera.hub.closed:
                del self.watched[camera_id]
                camera.hub.unwatch_live(self.client)
        elsewhere: dict[str, set[int]] = {}
        for camera_id in self.wanted.cameras:
            found = self.svc.cameras.get(camera_id)
            if found is None:
                node = self._node_of(camera_id)
                if node is not None:
                    elsewhere.setdefault(node, set()).add(camera_id)
                continue
            if found.hub.closed:
                continue
            if self.watched.get(camera_id) != (found, width):
                found.hub.watch_live(self.client, camera_id, width)
                self.watched[camera_id] = (found, width)
        self._follow(elsewhere, width)
        self.shown = frozenset(self.watched).union(*elsewhere.values())

    def _node_of(self, camera_id: int) -> str | None:
        if self.relayed or self.svc.relay is None:
            return None
        with contextlib.suppress(HTTPException):  # No such camera: nothing to show.
            return self.svc.node_of(camera_id)
        return None

    def _follow(self, elsewhere: dict[str, set[int]], width: int) -> None:
        for node in set(self.feeds) - set(elsewhere):
            self.feeds.pop(node).close()
        relay = self.svc.relay
        for node, cameras in elsewhere.items():
            if node not in self.feeds and relay is not None:
                self.feeds[node] = NodeFeed(relay, node, self.client.offer)
            self.feeds[node].watch(frozenset(cameras), width)

    def close(self) -> None:
        for camera, _ in self.watched.values():
            camera.hub.unwatch_live(self.client)
        self.watched.clear()
        for feed in self.feeds.values():
            feed.close()
        self.feeds.clear()


@router.websocket("/ws/live")
async def live(socket: WebSocket) -> None:
    svc = services(socket)
    await socket.accept()
    client = LiveClient(asyncio.get_running_loop())
    session = LiveSession(svc, client, relayed=is_relayed(socket))
    reader = asyncio.create_task(_read_watches(socket, session))
    try:
        while not svc.closing and not reader.done():
            if client.resync:
                client.resync = False
                session.sync()
            messages = await client.take()
            for camera_id, message in messages.items():
                if camera_id in session.shown:  # Not one unwatched since it came.
                    await socket.send_bytes(message)
        if svc.closing:
            with contextlib.suppress(Exception):
                await socket.close(1001)
    except (WebSocketDisconnect, RuntimeError, OSError):
        return
    finally:
        reader.cancel()
        client.close()
        session.close()


async def _read_watches(socket: WebSocket, session: LiveSession) -> None:
    """Take each watch message as it comes; until the client goes or sends a bad one."""
    try:
        while True:
            message = await socket.receive()
            if message["type"] == "websocket.disconnect":
                return
            text = message.get("text")
            try:
                if text is None:
                    raise WatchError("messages are JSON text, not binary")
                watch = parse_watch(text)
            except WatchError as refused:
                await socket.close(UNSUPPORTED, str(refused))
                return
            if watch is not None:
                session.want(watch)
    except (WebSocketDisconnect, RuntimeError, OSError):
        return
    finally:
        session.client.wake()  # The sending task sees that the client is gone.
