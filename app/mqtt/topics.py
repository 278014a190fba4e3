"""Vigil's topic names under the prefix ``<p>`` (``VIGIL_MQTT_PREFIX``, default ``vigil``).

State topics are retained; ``.../set`` topics are the commands Vigil listens to.

    <p>/status                          online | offline (the will)
    <p>/cameras/<id>/motion             ON | OFF
    <p>/cameras/<id>/active             ON | OFF
    <p>/cameras/<id>/active/set         ON | OFF        -> Activate | Stop
    <p>/cameras/<id>/sensitivity        1..255 | auto
    <p>/cameras/<id>/sensitivity/set    1..255 | auto   -> PATCH sensitivity
    <p>/cameras/<id>/event              alarm and motion_end, JSON as on /ws (not retained)
    <p>/cameras/<id>/snapshot           the latest alarm's JPEG
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

ON, OFF = "ON", "OFF"
ONLINE, OFFLINE = "online", "offline"
AUTO = "auto"

STATES = ("motion", "active", "sensitivity", "snapshot")
"""A camera's retained topics."""

Command = Literal["active", "sensitivity"]
COMMANDS: tuple[Command, ...] = ("active", "sensitivity")


@dataclass(frozen=True)
class Topics:
    prefix: str

    @property
    def status(self) -> str:
        return f"{self.prefix}/status"

    def camera(self, camera_id: int, name: str) -> str:
        """``name`` is ``motion``, ``active``, ``sensitivity``, ``event`` or ``snapshot``."""
        return f"{self.prefix}/cameras/{camera_id}/{name}"

    def command(self, camera_id: int, name: Command) -> str:
        return f"{self.camera(camera_id, name)}/set"

    def subscriptions(self) -> list[str]:
        """What Vigil subscribes to: the commands, and the retained ``active`` states, which
        tell which cameras the broker still holds (a camera deleted while it was away)."""
        wild = f"{self.prefix}/cameras/+"
        return [*(f"{wild}/{name}/set" for name in COMMANDS), f"{wild}/active"]

    def events(self) -> str:
        """Every camera's ``event`` topic: with several nodes, each hears the others'."""
        return f"{self.prefix}/cameras/+/event"

    def parse(self, topic: str) -> tuple[int, str] | None:
        """``(camera_id, rest)`` of a camera's topic (``rest``: ``active/set``, ``active``...),
        None for any other topic."""
        head = f"{self.prefix}/cameras/"
        if not topic.startswith(head):
            return None
        number, _, rest = topic[len(head) :].partition("/")
        if not (number.isascii() and number.isdigit()) or str(int(number)) != number or not rest:
            return None
        return int(number), rest


def on_off(value: bool) -> str:
    return ON if value else OFF


def parse_on_off(payload: str) -> bool | None:
    """``ON`` / ``OFF`` (any case, spaces around allowed); None for anything else."""
    return {ON: True, OFF: False}.get(payload.strip().upper())


def sensitivity_text(value: float | None) -> str:
    """A sensitivity as its topic carries it: ``auto``, ``40``, or ``12.5``."""
    if value is None:
        return AUTO
    return str(int(value)) if float(value).is_integer() else repr(float(value))


def parse_sensitivity(payload: str) -> float | None:
    """A ``sensitivity/set`` payload: a grey-level threshold from 1 to 255, or ``auto``
    (None). ValueError, with the reason, for anything else (as the API's PATCH refuses
    it)."""
    text = payload.strip()
    if text.lower() == AUTO:
        return None
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"not a number or 'auto': {text[:40]!r}") from None
    if not math.isfinite(value) or not 1 <= value <= 255:
        raise ValueError(f"sensitivity is a grey-level threshold from 1 to 255, not {text[:40]}")
    return value
