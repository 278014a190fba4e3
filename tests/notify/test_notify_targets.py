"""Apprise URLs as Vigil reads and shows them (real Apprise, no network), and the words of
an alarm's message."""

from __future__ import annotations

import time

import pytest

from app.notify.message import alarm_body, alarm_title, clock, describe
from app.notify.targets import Destination, TargetError, mask_in, masked, plugin_for

TOKEN = "AAHfakeBotTokenNotReal123"


@pytest.mark.parametrize(
    ("url", "shown"),
    [
        # As a camera's source is shown: user:password@ and secret parameters.
        ("json://vigil:pw@127.0.0.1:8080/hook?a=1", "json://vigil:***@127.0.0.1:8080/hook?a=1"),
        ("ntfys://me:pass@ntfy.example.net/door", "ntfys://me:***@ntfy.example.net/door"),
        ("mailtos://me:secret@example.com?to=a@b.c", "mailtos://me:***@example.com?to=a@b.c"),
        ("json://h/?token=abc123", "json://h/?token=***"),
        # What Apprise marks private for the service, wherever it stands in the URL.
        (f"tgram://123456789:{TOKEN}/4242", "tgram://***:***/4242"),
        (f"discord://98765/{TOKEN}", "discord://***/***"),
        ("pover://userkey123@apptoken456", "pover://***@***"),
        (f"gotify://push.example.net/{TOKEN}", "gotify://push.example.net/***"),
        ("slack://TokenA/TokenB/TokenC/#alerts", "slack://***/***/***/#alerts"),
        ("matrix://me:pass@matrix.example.net/#room", "matrix://me:***@matrix.example.net/#room"),
        # A webhook's HTTP headers, where credentials go.
        ("json://h/hook?+Authorization=Bearer%20xyz", "json://h/hook?+Authorization=***"),
        # Nothing secret: as it is.
        ("ntfys://door-topic", "ntfys://door-topic"),
        (
            "mailto://127.0.0.1:25?mode=insecure&from=vigil@example.com",
            "mailto://127.0.0.1:25?mode=insecure&from=vigil@example.com",
        ),
    ],
)
def test_secrets_are_masked_as_camera_passwords_are_and_as_apprise_knows_them(
    url: str, shown: str
) -> None:
    assert masked(url) == shown
    destination = Destination(url)
    assert destination.shown == shown and destination.url == url


def test_a_reason_names_no_secret() -> None:
    url = f"tgram://123456789:{TOKEN}/4242"
    assert mask_in(f"bot 123456789:{TOKEN} refused", url) == "bot *** refused"
    assert mask_in(f"token {TOKEN}", url) == "token ***"
    assert mask_in("password pw9 wrong", "json://u:pw9@h/") == "password *** wrong"
    with pytest.raises(TargetError) as refused:
        plugin_for(f"tgram://{TOKEN}/4242")
    assert "Telegram" in str(refused.value) and TOKEN not in str(refused.value)


@pytest.mark.parametrize(
    ("url", "said"),
    [
        ("", "give an Apprise URL"),
        ("ntfys", "not a URL"),
        ("ftp://host/x", "Apprise knows no service ftp://"),
        ("discord://1234", "Apprise cannot use this Discord URL"),
        ("json://", "Apprise cannot use this JSON URL"),
    ],
)
def test_urls_apprise_cannot_use_are_refused_saying_why(url: str, said: str) -> None:
    with pytest.raises(TargetError, match=said):
        plugin_for(url)


ALARM = {
    "type": "alarm",
    "camera_id": 3,
    "camera_name": "Front door",
    "event_id": 12,
    "ts": 1_800_000_000.5,
    "frame": 40,
    "boxes": [[10, 20, 40, 30]],
    "objects": [
        {
            "track_id": 4,
            "box": [10, 20, 40, 30],
            "area": 1012.4,
            "speed_px_s": 88.6,
            "distance_px": 3.5,
        },
        {
            "track_id": None,
            "box": [0, 0, 5, 6],
            "area": 21.0,
            "speed_px_s": 0.0,
            "distance_px": 0.0,
        },
    ],
    "snapshot": "/api/snapshots/88.jpg",
    "snapshot_id": 88,
    "difference": "/api/snapshots/89.jpg",
}


def test_an_alarm_s_message_says_when_what_moved_and_where_to_see_it() -> None:
    assert alarm_title(ALARM) == "Motion on Front door"
    when = time.strftime("%Y-%m-%d %H:%M:%S %Z", time.localtime(ALARM["ts"]))
    assert clock(ALARM["ts"]) == when
    assert alarm_body(ALARM, "https://vigil.example.net").splitlines() == [
        f"Motion on Front door at {when}.",
        "2 objects moving:",
        "- #4: 40×30 px box, 1,012 px moving, 89 px/s",
        "- 5×6 px box, 21 px moving, 0 px/s",
        "Event 12, camera 3.",
        "Snapshot: https://vigil.example.net/api/snapshots/88.jpg",
        "Dashboard: https://vigil.example.net/",
    ]
    # No public URL: no links. A later alarm of the event says since when it moves.
    later = alarm_body({**ALARM, "ts": ALARM["ts"] + 40}, "", started=ALARM["ts"])
    since = time.strftime("%H:%M:%S", time.localtime(ALARM["ts"]))
    assert later.splitlines()[0].endswith(f"(since {since}).")
    assert later.startswith("Still moving on Front door at ") and "http" not in later
    # A snapshot the disk refused is said; many objects are counted past five.
    crowd = {**ALARM, "snapshot": None, "snapshot_id": None, "objects": [ALARM["objects"][0]] * 7}
    body = alarm_body(crowd)
    assert "- and 2 more" in body and "No snapshot: the server could not save it." in body
    assert describe(ALARM["objects"][0]) == "#4: 40×30 px box, 1,012 px moving, 89 px/s"
