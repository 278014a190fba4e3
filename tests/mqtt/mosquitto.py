"""A real Mosquitto broker for the tests, and a real MQTT client that watches it.

The broker is Debian's ``mosquitto`` (``/usr/sbin/mosquitto``), run in the foreground on a
free loopback port with a config file of the test's own; tests skip, saying so, where it
is not installed. The watcher is aiomqtt, the client Vigil itself uses, in a thread of its
own.
"""

from __future__ import annotations

import asyncio
import getpass
import shutil
import signal
import subprocess
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import aiomqtt
import pytest

from tests.api.vigil_livekit import free_port, wait_for

MOSQUITTO = "/usr/sbin/mosquitto"
MOSQUITTO_PASSWD = shutil.which("mosquitto_passwd") or "/usr/bin/mosquitto_passwd"


def need_mosquitto() -> None:
    if not Path(MOSQUITTO).exists():
        pytest.skip(
            f"Mosquitto is not installed ({MOSQUITTO} is missing: apt-get install mosquitto)"
        )


class Mosquitto:
    """One broker: ``start()`` it, ``kill()`` it (SIGKILL, as a crash), ``start()`` it again
    on the same port. With ``users`` ({name: password}) only they may connect; with
    ``persistence`` its retained messages outlive a kill (saved at every change)."""

    def __init__(
        self,
        folder: Path,
        users: dict[str, str] | None = None,
        persistence: bool = False,
        port: int | None = None,
    ) -> None:
        need_mosquitto()
        self.folder = folder
        folder.mkdir(parents=True, exist_ok=True)
        self.port = port or free_port()
        self.users = users
        self.persistence = persistence
        self.process: subprocess.Popen[bytes] | None = None
        self.log = folder / "mosquitto.log"

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    def _config(self) -> Path:
        # As root it would become user "mosquitto", who cannot read the test's folder.
        lines = [f"listener {self.port} 127.0.0.1", f"user {getpass.getuser()}"]
        if self.users is None:
            lines.append("allow_anonymous true")
        else:
            passwords = self.folder / "passwords"
            passwords.write_text("")
            for user, password in self.users.items():
                subprocess.run([MOSQUITTO_PASSWD, "-b", str(passwords), user, password], check=True)
            lines += ["allow_anonymous false", f"password_file {passwords}"]
        if self.persistence:
            lines += [
                "persistence true",
                f"persistence_location {self.folder}/",
                "autosave_interval 1",
                "autosave_on_changes true",
            ]
        config = self.folder / "mosquitto.conf"
        config.write_text("\n".join(lines) + "\n")
        return config

    def start(self) -> Mosquitto:
        config = self._config()
        with self.log.open("ab") as log:
            self.process = subprocess.Popen(
                [MOSQUITTO, "-c", str(config)], stdout=log, stderr=subprocess.STDOUT
            )
        wait_for(self._listening, 10, f"mosquitto to listen on {self.port}")
        return self

    def _listening(self) -> bool:
        if self.process is not None and self.process.poll() is not None:
            raise AssertionError(f"mosquitto exited: {self.log.read_text()[-2000:]}")
        return f"Opening ipv4 listen socket on port {self.port}" in self.log.read_text()

    def kill(self) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.send_signal(signal.SIGKILL)
            self.process.wait(10)
        self.process = None

    def stop(self) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(10)
        self.process = None


@dataclass(frozen=True)
class Received:
    topic: str
    payload: bytes
    retain: bool
    at: float
    """time.time() when it arrived."""

    @property
    def text(self) -> str:
        return self.payload.decode()


class Watcher:
    """A test's MQTT client: subscribes to ``topics`` and keeps every message, in order.
    ``publish`` sends from it (a command, as Home Assistant would)."""

    def __init__(self, port: int, topics: tuple[str, ...] = ("#",)) -> None:
        self.port = port
        self.topics = topics
        self.messages: list[Received] = []
        self._lock = threading.Lock()
        self._ready = threading.Event()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._client: aiomqtt.Client | None = None
        self._stop: asyncio.Event | None = None
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=lambda: asyncio.run(self._run()), daemon=True)

    def __enter__(self) -> Watcher:
        self._thread.start()
        wait_for(lambda: self._ready.is_set() or self.error, 10, "the MQTT watcher to connect")
        if self.error:
            raise self.error
        return self

    def __exit__(self, *exc: object) -> None:
        if self._loop is not None and self._stop is not None:
            self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(10)

    async def _run(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        try:
            async with aiomqtt.Client("127.0.0.1", self.port, timeout=5) as client:
                self._client = client
                for topic in self.topics:
                    await client.subscribe(topic, qos=1)
                self._ready.set()
                reader = asyncio.create_task(self._read(client))
                await self._stop.wait()
                reader.cancel()
        except BaseException as exc:
            self.error = exc
            self._ready.set()

    async def _read(self, client: aiomqtt.Client) -> None:
        async for message in client.messages:
            payload = message.payload
            data = payload if isinstance(payload, bytes) else str(payload).encode()
            with self._lock:
                self.messages.append(
                    Received(str(message.topic), data, message.retain, time.time())
                )

    def publish(self, topic: str, payload: str | bytes, retain: bool = False) -> None:
        assert self._loop is not None and self._client is not None
        client = self._client
        future = asyncio.run_coroutine_threadsafe(
            client.publish(topic, payload, qos=1, retain=retain), self._loop
        )
        future.result(10)

    def on(self, topic: str) -> list[Received]:
        with self._lock:
            return [m for m in self.messages if m.topic == topic]

    def last(self, topic: str) -> Received | None:
        found = self.on(topic)
        return found[-1] if found else None

    def matching(self, predicate: Callable[[Received], bool]) -> list[Received]:
        with self._lock:
            return [m for m in self.messages if predicate(m)]

    def wait(
        self, topic: str, payload: str | bytes | None = None, timeout: float = 15.0, after: int = 0
    ) -> Received:
        """The first message on ``topic`` (with ``payload``, if given) among those received
        from index ``after`` on (``mark()``)."""
        want = payload.encode() if isinstance(payload, str) else payload

        def found() -> Received | None:
            with self._lock:
                tail = self.messages[after:]
            return next(
                (m for m in tail if m.topic == topic and (want is None or m.payload == want)),
                None,
            )

        return wait_for(found, timeout, f"{topic} {payload!r} on the broker")

    def index(self, received: Received) -> int:
        """Where ``received`` is among the messages: ``wait(after=index(m) + 1)`` sees only
        those that came after it."""
        with self._lock:
            return next(i for i, m in enumerate(self.messages) if m is received)

    def mark(self) -> int:
        """Where the messages stand now: ``wait(after=mark())`` sees only newer ones."""
        with self._lock:
            return len(self.messages)


def retained(port: int, topics: tuple[str, ...], settle_s: float = 0.5) -> dict[str, bytes]:
    """What the broker holds retained under ``topics`` now, as a new subscriber sees it."""
    with Watcher(port, topics) as watcher:
        time.sleep(settle_s)
        return {m.topic: m.payload for m in watcher.matching(lambda m: m.retain)}


def mqtt_settings(broker: Mosquitto, **more: Any) -> dict[str, Any]:
    """Settings overrides for a Vigil on ``broker``: quick reconnects for tests."""
    return {"mqtt_url": broker.url, "mqtt_reconnect_max_s": 1.0, **more}
