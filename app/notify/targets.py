"""Apprise, as Vigil uses it: a target's URL checked, shown with its secrets masked, and sent to.

Apprise (``apprise`` on PyPI) turns one URL into a message to one of 100+ services:
``ntfys://topic``, ``tgram://bot-token/chat-id``, ``mailtos://user:pass@example.com``,
``json://host/path``... Its ``notify`` is synchronous; the notifier calls ``send`` from a
thread of its own per target, and Apprise's ``timeout`` bounds each call.

Apprise's own log lines are not passed on to Vigil's log: one per attempt would flood it
while a target is down. Each call keeps its own in its result, and ``send`` makes the
reason of a failure from them; the notifier logs once per spell of failures.
"""

from __future__ import annotations

import logging
import re
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import apprise
from apprise.attachment.file import AttachFile
from apprise.manager_plugins import NotificationManager

from app.sources.live import MASK, _passwords, without_password

APPRISE_LOGGER = logging.getLogger("apprise")
SERVICES = NotificationManager()
"""Apprise's services, by URL scheme."""
WIKI = "https://github.com/caronc/apprise/wiki"
"""Where every service's URL is described."""
MAX_URL = 4000
"""Characters in a target's URL: a webhook's headers and parameters fit in plenty."""

_PARTS = re.compile(r"([/:@?&=#])")
"""What a URL is cut at into the parts a secret is masked as a whole in."""

CAUSES = (
    ("Connection refused", "connection refused"),
    ("Read timed out", "no answer in time"),
    ("timed out", "timed out"),
    ("Name or service not known", "unknown host"),
    ("Temporary failure in name resolution", "host name not resolved"),
    ("No route to host", "no route to host"),
    ("Network is unreachable", "network unreachable"),
    ("certificate verify failed", "TLS certificate not trusted"),
    ("Connection reset by peer", "connection reset"),
    ("Remote end closed connection", "connection closed without an answer"),
)
"""Words of a socket's error (as Apprise logs it, at debug level, with the address in
full) and what a failure's reason says of them: the cause, never the address."""


def quiet_apprise() -> None:
    """Apprise's log lines stay in each call's result (``send`` reads them), not in Vigil's
    log. DEBUG, so a socket's error, which says why a connection failed, is among them."""
    APPRISE_LOGGER.propagate = False
    APPRISE_LOGGER.setLevel(logging.DEBUG)


class TargetError(ValueError):
    """A URL Apprise cannot send to; the message says why, with no secret of it."""


@dataclass(frozen=True)
class Message:
    """What one notification says: a title, a plain-text body and a picture, if any."""

    title: str
    body: str
    attachment: Path | None = None
    attachment_name: str | None = None
    notify_type: str = "info"


@dataclass(frozen=True)
class Outcome:
    """How one attempt went: sent, or why not (with no secret in it)."""

    ok: bool
    error: str | None = None
    elapsed_s: float = 0.0


def asset(public_url: str = "") -> apprise.AppriseAsset:
    """Who sends: Vigil. Apprise keeps nothing on disk (no persistent store)."""
    return apprise.AppriseAsset(
        app_id="Vigil",
        app_desc="Vigil motion detection",
        app_url=public_url or "https://github.com/caronc/apprise",
        storage_mode="memory",
    )


def plugin_for(url: str, assets: apprise.AppriseAsset | None = None) -> Any:
    """Apprise's plugin for ``url``, ready to send; TargetError saying why not."""
    text = url.strip()
    if not text:
        raise TargetError("give an Apprise URL, such as ntfys://my-topic")
    if len(text) > MAX_URL:
        raise TargetError(f"a target's URL has at most {MAX_URL} characters")
    if any(ord(c) < 32 or 127 <= ord(c) < 160 for c in text):
        raise TargetError("a target's URL must not contain control characters")
    scheme = text.partition("://")[0].lower() if "://" in text else ""
    if not scheme:
        raise TargetError(
            f"not a URL: an Apprise URL starts with its service, as ntfys:// ({WIKI})"
        )
    if scheme not in SERVICES:
        raise TargetError(f"Apprise knows no service {scheme}:// (its services: {WIKI})")
    with _apprise_log() as said:
        plugin = apprise.Apprise.instantiate(text, asset=assets or asset())
    if plugin is None:
        service = getattr(SERVICES[scheme], "service_name", scheme)
        reason = _mask_url_parts(_reason(said, text), text) or "Apprise cannot read it"
        raise TargetError(f"Apprise cannot use this {service} URL: {reason} ({WIKI})")
    return plugin


def masked(url: str) -> str:
    """``url`` as the API, the page and the log show it: its secrets replaced by ``MASK``.

    First as a camera's source is shown (``without_password``: the password of
    ``user:password@`` and of parameters such as ``?token=``), then every value Apprise
    marks private for the URL's service, wherever it stands as a whole part of the URL:
    a Telegram bot's token (``tgram://***:***/chat-id``), a Discord webhook's id and
    token, Pushover's keys, a Gotify token... and the values of HTTP headers given as
    ``+Name=value`` (a webhook's credentials). Should Apprise have read a secret in a
    form the URL does not hold as a part, Apprise's own private form of the URL is shown.
    """
    shown = without_password(url)
    secrets = _secrets(url)
    if not secrets:
        return shown
    result = _mask_parts(shown, secrets)
    if any(len(secret) >= 4 and secret in result for secret in secrets):
        try:
            private = plugin_for(url).url(privacy=True)
        except TargetError:
            return url.partition("://")[0] + "://" + MASK
        return _mask_parts(without_password(private), secrets)
    return result


def mask_in(text: str, url: str) -> str:
    """``text`` (a reason, a log line) with every secret of ``url`` in it masked."""
    # The camera sources' own reading of passwords (user:password@, ?token=...).
    passwords = {password for _, password in _passwords(url)}
    for secret in sorted(_secrets(url) | passwords, key=len, reverse=True):
        if len(secret) >= 3:
            text = text.replace(secret, MASK)
    return text


class Destination:
    """A target's URL made ready to send to: Apprise's plugin for it (TargetError if there
    is none), its masked form and its service's name. One thread sends through it at a
    time (the plugin keeps the time of its last request, to pace them)."""

    def __init__(self, url: str, public_url: str = "") -> None:
        self.url = url.strip()
        self.plugin = plugin_for(self.url, asset(public_url))
        self.shown = masked(self.url)
        self.service = str(self.plugin.service_name)
        self._apprise = apprise.Apprise(asset=self.plugin.asset)
        self._apprise.add(self.plugin)

    def send(self, message: Message, timeout_s: float) -> Outcome:
        """One attempt to send ``message``, within ``timeout_s`` in all (Apprise stops
        waiting then; its call may end later in a thread of its own)."""
        started = time.monotonic()
        attach = None
        if message.attachment is not None:
            attach = AttachFile(str(message.attachment), name=message.attachment_name)
        try:
            result = self._apprise.notify(
                body=message.body,
                title=message.title,
                notify_type=message.notify_type,
                body_format=apprise.NotifyFormat.TEXT,
                attach=attach,
                timeout=timeout_s,
                log_level=logging.DEBUG,
            )
        except Exception as exc:  # A plugin's own bug must not end the worker.
            return Outcome(False, f"Apprise failed: {type(exc).__name__}", _since(started))
        if result:
            return Outcome(True, None, _since(started))
        if result.timeout_count:
            return Outcome(False, f"no answer within {timeout_s:g} s", _since(started))
        logs = [(entry.level, entry.message) for entry in result.logs()]
        reason = _reason(logs, self.url) or f"{self.service} did not take the message"
        return Outcome(False, reason, _since(started))


def _since(started: float) -> float:
    return round(time.monotonic() - started, 3)


def _reason(logs: list[tuple[str, str]], url: str) -> str:
    """Why Apprise failed, from its log lines of one call: its warnings and errors, with
    the cause a socket's error names, and no secret of ``url``."""
    warnings = [text for level, text in logs if level == "WARNING"]
    errors = [text for level, text in logs if level in ("ERROR", "CRITICAL")]
    said = [text.strip().rstrip(".") for text in warnings or errors]
    causes = [
        cause
        for level, text in logs
        if text.startswith("Socket Exception")
        for words, cause in CAUSES
        if words in text
    ]
    reason = "; ".join(dict.fromkeys(said[-2:]))
    if causes:
        reason = f"{reason} ({causes[0]})" if reason else causes[0]
    return mask_in(reason.replace(url, url.partition("://")[0] + "://..."), url)


def _mask_url_parts(text: str, url: str) -> str:
    """``text`` with each part of ``url`` (but its scheme) of 6 characters or more masked:
    for a URL Apprise could not read, whose secrets it cannot tell."""
    scheme, _, rest = url.partition("://")
    for part in sorted(set(_pieces(rest)), key=len, reverse=True):
        if len(part) >= 6 and part not in (scheme, MASK):
            text = text.replace(part, MASK)
    return text


def _mask_parts(url: str, secrets: set[str]) -> str:
    scheme, sep, rest = url.partition("://")
    parts = _PARTS.split(rest)
    return (
        scheme
        + sep
        + "".join(MASK if part in secrets or unquote(part) in secrets else part for part in parts)
    )


def _secrets(url: str) -> set[str]:
    """The values Apprise marks private for ``url``'s service, as read from it, and its
    HTTP headers' values, each also cut into the parts of a URL (a Telegram bot token,
    ``123:abc``, stands in the URL as two)."""
    scheme = url.partition("://")[0].lower()
    if scheme not in SERVICES:
        return set()
    service = SERVICES[scheme]
    try:
        read = service.parse_url(url.strip())
    except Exception:  # A plugin's parser failing on odd input reads no secret.
        read = None
    if not read:
        return set()
    names: set[str] = set()
    for templates in (service.template_tokens, service.template_args):
        for name, spec in templates.items():
            if spec.get("private"):
                names.update((name, spec.get("map_to", name)))
    values: list[Any] = [read.get(name) for name in names]
    values.extend((read.get("headers") or {}).values())
    found: set[str] = set()
    for value in values:
        for item in value if isinstance(value, (list, tuple, set)) else [value]:
            if isinstance(item, str) and item:
                found.add(item)
                found.update(_pieces(item))
    return found


def _pieces(text: str) -> list[str]:
    """``text`` cut where a URL's parts meet, without the marks between them."""
    return [part for part in _PARTS.split(text) if part and not _PARTS.fullmatch(part)]


@contextmanager
def _apprise_log() -> Iterator[list[tuple[str, str]]]:
    """Apprise's log lines of this thread while inside (another thread's are not)."""
    said: list[tuple[str, str]] = []
    me = threading.get_ident()

    class Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            if record.thread == me:
                said.append((record.levelname, record.getMessage()))

    handler = Keep(logging.WARNING)
    APPRISE_LOGGER.addHandler(handler)
    try:
        yield said
    finally:
        APPRISE_LOGGER.removeHandler(handler)
