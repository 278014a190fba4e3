"""What a notification says: an alarm's title and words (pure: no I/O, no Apprise).

An ``alarm`` message (its wire form, as the bus carries it) becomes a title, ``Motion on
<camera>``, and a plain-text body: when (the server's local time), what moved (each
object's box, area and speed), the event, and with ``VIGIL_PUBLIC_URL`` links to the
snapshot and the dashboard. The snapshot itself goes as an attachment (the notifier).
"""

from __future__ import annotations

import time
from typing import Any

from app.events.messages import Wire

OBJECTS_LISTED = 5
"""Objects named one by one; more are counted."""


def alarm_title(alarm: Wire) -> str:
    return f"Motion on {alarm['camera_name']}"


def alarm_body(alarm: Wire, public_url: str = "", started: float | None = None) -> str:
    """The words of an alarm's message. ``started``: when its event began, for a later
    alarm of an event (after ``VIGIL_NOTIFY_GAP_S``); None for the event's first."""
    name = alarm["camera_name"]
    when = clock(alarm["ts"])
    if started is None or started >= alarm["ts"]:
        lines = [f"Motion on {name} at {when}."]
    else:
        lines = [f"Still moving on {name} at {when} (since {clock(started, date=False)})."]
    objects: list[dict[str, Any]] = alarm.get("objects") or []
    if objects:
        noun = "object" if len(objects) == 1 else "objects"
        lines.append(f"{len(objects)} {noun} moving:")
        lines.extend(f"- {describe(item)}" for item in objects[:OBJECTS_LISTED])
        if len(objects) > OBJECTS_LISTED:
            lines.append(f"- and {len(objects) - OBJECTS_LISTED} more")
    lines.append(f"Event {alarm['event_id']}, camera {alarm['camera_id']}.")
    if alarm.get("snapshot") is None:
        lines.append("No snapshot: the server could not save it.")
    if public_url:
        if alarm.get("snapshot"):
            lines.append(f"Snapshot: {public_url}{alarm['snapshot']}")
        lines.append(f"Dashboard: {public_url}/")
    return "\n".join(lines)


def describe(item: dict[str, Any]) -> str:
    """One object: ``#3: 40×40 px box, 1,600 px moving, 90 px/s``."""
    _, _, width, height = item["box"]
    words = f"{width}×{height} px box, {item['area']:,.0f} px moving, {item['speed_px_s']:.0f} px/s"
    track = item.get("track_id")
    return f"#{track}: {words}" if track is not None else words


def clock(ts: float, date: bool = True) -> str:
    """A time as the server's clock reads it, with its zone: ``2026-12-05 09:44:54 CET``."""
    local = time.localtime(ts)
    return time.strftime("%Y-%m-%d %H:%M:%S %Z" if date else "%H:%M:%S", local)


def sample_body(public_url: str = "") -> str:
    """The words of ``POST /api/notifications/{id}/test``'s message."""
    lines = [
        f"A test from Vigil at {clock(time.time())}: this target works.",
        "When something moves, a message like this one comes, with its snapshot.",
    ]
    if public_url:
        lines.append(f"Dashboard: {public_url}/")
    return "\n".join(lines)
