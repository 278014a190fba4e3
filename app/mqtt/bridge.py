"""The MQTT bridge: two asyncio tasks on the server's event loop.

``follow`` reads the server's event bus (its own subscriber queue, as each /ws client has)
and keeps the ``Mirror``; what changed goes to the outbox, at once, while a broker is
connected, and is dropped while none is (the mirror keeps the state). ``stay_connected``
connects, subscribes to the commands, publishes ``everything()`` (the state as it is now),
then sends the outbox and takes commands until the connection is lost; then it waits
(half a second, doubling up to ``VIGIL_MQTT_RECONNECT_MAX_S``) and connects again.

Nothing here blocks: the socket is paho-mqtt's, driven by the event loop (aiomqtt);
reading a snapshot's JPEG and acting on a command (the database, the camera processes)
run in threads. A broker that is down or slow costs MQTT only: /ws has its own queue, the
camera workers publish to the bus without waiting, and ``/api/health`` says why MQTT is
down.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import os
import socket
import ssl
import time
from collections.abc import Container, Iterable
from dataclasses import dataclass
from typing import Any, Protocol

import aiomqtt

from app.mqtt.broker import Broker
from app.mqtt.discovery import Discovery
from app.mqtt.mirror import CameraInfo, Mirror, Publication, SnapshotRef
from app.mqtt.topics import OFFLINE, ONLINE, Topics, parse_on_off, parse_sensitivity
from app.workers.bus import EventBus, Subscriber

log = logging.getLogger("vigil.mqtt")

RECONNECT_MIN_S = 0.5
TIMEOUT_S = 5.0
"""For connecting, and for the broker's acknowledgement of each message (QoS 1)."""
KEEPALIVE_S = 30
"""A broker gone silent (no FIN: a cable pulled) is noticed within 1.5 times this."""
REFRESH_S = 1.0
"""How often the cameras are compared with the mirror even without a bus message (a
camera deleted sends none)."""
OUTBOX_LIMIT = 10_000
"""Publications waiting for a slow broker; past it they are dropped and the whole state
is sent again instead."""
STOP_TIMEOUT_S = 3.0
QOS = 1
RELAYED = ("alarm", "motion_end")


class Control(Protocol):
    """What the bridge needs of the server (``Services``)."""

    def cameras(self) -> list[CameraInfo]:
        """The cameras as they run now; called on the event loop, so from memory."""
        ...

    def set_active(self, camera_id: int, active: bool) -> bool:
        """Activate or Stop, as the API does; False: no such camera. Blocking."""
        ...

    def set_sensitivity(self, camera_id: int, sensitivity: float | None) -> bool:
        """Change the sensitivity (None: automatic), as the API's PATCH does; False: no
        such camera. Blocking."""
        ...

    def snapshot_jpeg(self, snapshot_id: int) -> bytes | None:
        """A snapshot's JPEG; None when it is gone. Blocking."""
        ...

    def latest_snapshots(self, camera_ids: list[int]) -> dict[int, int]:
        """Each camera's latest alarm snapshot (its id) from the database. Blocking."""
        ...

    def elsewhere(self) -> Container[int]:
        """The site's cameras that run on another node (or none yet), from memory: their
        topics are that node's, not to be removed here."""
        ...


@dataclass(frozen=True)
class _Flush:
    """Put in the outbox at shutdown: set when everything before it has been sent."""

    done: asyncio.Event


class MqttBridge:
    def __init__(
        self,
        broker: Broker,
        prefix: str,
        discovery_prefix: str,
        control: Control,
        reconnect_max_s: float = 30.0,
        node: str | None = None,
    ) -> None:
        """``node``: this node's name, with several nodes on the broker: the others' alarms
        and ``motion_end`` on it are relayed onto this node's bus, for its pages; and as
        ``<p>/status`` is the site's, a node that hears it ``offline`` (another node's will,
        or its clean stop) says ``online`` again while it runs."""
        self.broker = broker
        self.node = node
        self.topics = Topics(prefix)
        discovery = Discovery(discovery_prefix, self.topics) if discovery_prefix else None
        self.mirror = Mirror(self.topics, discovery)
        self.control = control
        self.reconnect_max_s = max(reconnect_max_s, RECONNECT_MIN_S)
        # The broker drops a client when another connects with its identifier.
        self.identifier = f"vigil-{(node or socket.gethostname())[:32]}-{os.getpid()}"
        self._bus: EventBus | None = None
        self._queue: Subscriber | None = None
        self._outbox: asyncio.Queue[Publication | _Flush] | None = None
        self._tasks: list[asyncio.Task[None]] = []
        self._next_refresh = 0.0
        self._state = "disconnected"
        self._reason = "not connected yet"
        self._since = time.time()
        self._overflowed = False
        self._closing = False

    # Life -------------------------------------------------------------------------------

    def subscribe(self, bus: EventBus) -> None:
        """Listen to the bus from now on (on the event loop, before the cameras start)."""
        self._bus = bus
        self._queue = bus.subscribe()

    def start(self) -> None:
        """Start following the bus and connecting (on the event loop, the cameras started)."""
        assert self._queue is not None, "subscribe() first"
        self._tasks = [
            asyncio.create_task(self._follow(self._queue), name="mqtt-follow"),
            asyncio.create_task(self._stay_connected(), name="mqtt-connection"),
        ]

    async def stop(self) -> None:
        """Say the cameras' events are over and Vigil is ``offline``, then disconnect (the
        broker does not send the will for a clean disconnect). Within ``STOP_TIMEOUT_S``."""
        self._closing = True
        follow = self._tasks[0] if self._tasks else None
        if follow is not None:
            follow.cancel()
        outbox = self._outbox
        if self.connected and outbox is not None:
            done = asyncio.Event()
            for publication in self.mirror.closing():
                outbox.put_nowait(publication)
            outbox.put_nowait(_Flush(done))
            try:
                await asyncio.wait_for(done.wait(), STOP_TIMEOUT_S)
            except TimeoutError:
                log.warning("MQTT: the broker did not take the last messages in time")
        for task in self._tasks:
            task.cancel()
        if self._tasks:
            await asyncio.wait(self._tasks, timeout=STOP_TIMEOUT_S)
        if self._bus is not None and self._queue is not None:
            self._bus.unsubscribe(self._queue)

    @property
    def connected(self) -> bool:
        return self._state == "connected"

    def health(self) -> dict[str, Any]:
        """``state`` (``connected`` or ``disconnected``), ``broker`` (no password),
        ``since`` (UNIX time), and ``reason`` while disconnected."""
        out: dict[str, Any] = {
            "state": self._state,
            "broker": str(self.broker),
            "since": round(self._since, 3),
        }
        if self._state != "connected":
            out["reason"] = self._reason
        return out

    # Following the server -----------------------------------------------------------------

    async def _follow(self, queue: Subscriber) -> None:
        self._refresh()
        try:
            ids = list(self.mirror.cameras)
            latest = await asyncio.to_thread(self.control.latest_snapshots, ids)
        except Exception:
            log.exception("MQTT: cannot read the cameras' latest snapshots")
            latest = {}
        self._send(self.mirror.seed_snapshots(latest))
        while True:
            try:
                message = await asyncio.wait_for(queue.get(), REFRESH_S)
            except TimeoutError:
                message = {}
            if message is None:  # The server is stopping.
                return
            try:
                self._follow_message(message)
                if time.monotonic() >= self._next_refresh:
                    self._refresh()
            except Exception:  # A surprise costs this message, not MQTT.
                log.exception("MQTT: cannot follow a %s message", message.get("type"))

    def _follow_message(self, message: dict[str, Any]) -> None:
        kind = message.get("type")
        if kind == "alarm":
            if message["camera_id"] not in self.mirror.cameras:
                self._refresh()  # Added a moment ago: its entities first.
            self._send(self.mirror.alarm(message))
        elif kind == "motion_end":
            self._send(self.mirror.motion_end(message))
        elif kind == "status" and "camera_id" in message:
            self._refresh()
        elif kind == "snapshots_deleted":
            self._send(self.mirror.snapshots_deleted(message["ids"]))

    def _refresh(self) -> None:
        self._next_refresh = time.monotonic() + REFRESH_S
        self._send(self.mirror.refresh(self.control.cameras(), self.control.elsewhere()))

    def _send(self, publications: Iterable[Publication]) -> None:
        """Queue ``publications`` for the broker, if one is connected (else the mirror's
        state goes out whole on the next connection)."""
        outbox = self._outbox
        if outbox is None or not self.connected:
            return
        publications = list(publications)
        if outbox.qsize() + len(publications) > OUTBOX_LIMIT:
            if not self._overflowed:
                log.warning("MQTT: the broker is too slow; sending the whole state again")
            self._overflowed = True
            _drain(outbox)
            publications = self.mirror.everything()
        for publication in publications:
            outbox.put_nowait(publication)

    # The connection -----------------------------------------------------------------------

    async def _stay_connected(self) -> None:
        backoff = RECONNECT_MIN_S
        tls: ssl.SSLContext | None = None
        while True:
            try:
                if self.broker.tls and tls is None:  # Reads the system's CAs: a thread.
                    tls = await asyncio.to_thread(ssl.create_default_context)
                await self._session(tls)
                reason = "the broker closed the connection"
            except aiomqtt.MqttError as exc:
                reason = str(exc) or type(exc).__name__
            except Exception as exc:  # A bug here must not end MQTT for good.
                log.exception("MQTT: unexpected failure")
                reason = f"{type(exc).__name__}: {exc}"
            was_connected = self.connected
            self._disconnected(reason)
            if was_connected:
                backoff = RECONNECT_MIN_S
            await asyncio.sleep(backoff)
            backoff = min(backoff * 2, self.reconnect_max_s)

    async def _session(self, tls: ssl.SSLContext | None) -> None:
        """One connection: subscribe, publish the whole state, then send and listen until
        it is lost (MqttError)."""
        client = aiomqtt.Client(
            self.broker.host,
            self.broker.port,
            username=self.broker.username,
            password=self.broker.password,
            identifier=self.identifier,
            will=aiomqtt.Will(self.topics.status, OFFLINE, qos=QOS, retain=True),
            tls_context=tls,
            timeout=TIMEOUT_S,
            keepalive=KEEPALIVE_S,
            clean_session=True,
        )
        async with client:
            relayed = [self.topics.events(), self.topics.status] if self.node is not None else []
            for topic in [*self.topics.subscriptions(), *relayed]:
                await client.subscribe(topic, qos=QOS)
            # The cameras as they are now, then all of it. A camera deleted while no broker
            # was connected is removed when its retained ``active`` comes back (_take).
            self._refresh()
            outbox: asyncio.Queue[Publication | _Flush] = asyncio.Queue()
            self._outbox = outbox
            self._connected()
            self._send(self.mirror.everything())
            sender = asyncio.create_task(self._deliver(client, outbox))
            listener = asyncio.create_task(self._listen(client))
            try:
                done, _ = await asyncio.wait(
                    {sender, listener}, return_when=asyncio.FIRST_COMPLETED
                )
            finally:
                self._outbox = None
                for task in (sender, listener):
                    task.cancel()
                await asyncio.gather(sender, listener, return_exceptions=True)
            for task in done:
                task.result()  # Its MqttError: why the connection ended.

    def _connected(self) -> None:
        self._state, self._reason, self._since = "connected", "", time.time()
        self._overflowed = False
        log.info("MQTT: connected to %s", self.broker)

    def _disconnected(self, reason: str) -> None:
        if self._state == "connected":
            log.warning("MQTT: lost %s: %s; reconnecting", self.broker, reason)
        elif reason != self._reason:
            log.warning(
                "MQTT: cannot reach %s: %s; trying again (at most every %g s)",
                self.broker,
                reason,
                self.reconnect_max_s,
            )
        if self._state == "connected" or reason != self._reason:
            self._since = time.time()
        self._state, self._reason = "disconnected", reason

    async def _deliver(
        self, client: aiomqtt.Client, outbox: asyncio.Queue[Publication | _Flush]
    ) -> None:
        while True:
            item = await outbox.get()
            if isinstance(item, _Flush):
                item.done.set()
                continue
            payload = item.payload
            if isinstance(payload, SnapshotRef):
                try:
                    jpeg = await asyncio.to_thread(self.control.snapshot_jpeg, payload.snapshot_id)
                except Exception:
                    log.exception("MQTT: cannot read snapshot %s", payload.snapshot_id)
                    continue
                if jpeg is None:  # Deleted meanwhile.
                    continue
                payload = jpeg
            await client.publish(item.topic, payload, qos=QOS, retain=item.retain)

    async def _listen(self, client: aiomqtt.Client) -> None:
        async for message in client.messages:
            try:
                await self._take(str(message.topic), _text(message.payload), message.retain)
            except Exception:
                log.exception("MQTT: cannot act on %s", message.topic)

    async def _take(self, topic: str, payload: str, retained: bool) -> None:
        """A message on a topic Vigil subscribes to: a command, or a retained ``active``
        of a camera the broker still holds; with several nodes, another node's event, or
        the site's status."""
        if topic == self.topics.status:
            if payload == OFFLINE and not self._closing:  # Another node's will: not the site's.
                self._send([Publication(self.topics.status, ONLINE)])
            return
        parsed = self.topics.parse(topic)
        if parsed is None:
            return
        camera_id, rest = parsed
        if rest == "event":
            self._relay(camera_id, payload)
            return
        if rest == "active":  # A retained state: cleared if its camera is no more.
            if retained and payload:
                self._refresh()
                gone = camera_id not in self.mirror.cameras
                if gone and camera_id not in self.control.elsewhere():
                    log.info("MQTT: camera %s is gone: removing it from the broker", camera_id)
                    self._send(self.mirror.removal(camera_id))
            return
        if retained:  # A command kept by the broker is stale: not obeyed at each connect.
            log.warning(
                "MQTT: ignored a retained command on %s (publish commands unretained)", topic
            )
            return
        if rest == "active/set":
            active = parse_on_off(payload)
            if active is None:
                log.warning("MQTT: ignored %s: %r is not ON or OFF", topic, payload[:40])
                return
            found = await asyncio.to_thread(self.control.set_active, camera_id, active)
        elif rest == "sensitivity/set":
            try:
                sensitivity = parse_sensitivity(payload)
            except ValueError as exc:
                log.warning("MQTT: ignored %s: %s", topic, exc)
                return
            found = await asyncio.to_thread(self.control.set_sensitivity, camera_id, sensitivity)
        else:
            return
        if not found:
            log.warning("MQTT: ignored %s: there is no camera %s", topic, camera_id)
        self._refresh()  # The new state, at once.

    def _relay(self, camera_id: int, payload: str) -> None:
        """Another node's ``alarm`` or ``motion_end`` (as on its /ws) onto this node's bus:
        its pages show every alarm of the site. This node's own, heard back, are left out,
        and so is anything else."""
        try:
            message = json.loads(payload)
        except ValueError:
            return
        if (
            not isinstance(message, dict)
            or message.get("type") not in RELAYED
            or message.get("camera_id") != camera_id
            or message.get("node") in (None, self.node)
            or self._bus is None
        ):
            return
        self._bus.publish(message)


def _text(payload: Any) -> str:
    if isinstance(payload, bytes | bytearray):
        return bytes(payload).decode("utf-8", "replace")
    return "" if payload is None else str(payload)


def _drain(queue: asyncio.Queue[Any]) -> None:
    with contextlib.suppress(asyncio.QueueEmpty):
        while True:
            queue.get_nowait()
