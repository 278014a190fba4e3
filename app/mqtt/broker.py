"""The broker's address, from ``VIGIL_MQTT_URL``: ``mqtt://user:password@host:1883`` or
``mqtts://...`` for TLS. User and password are percent-decoded (``p%40ss`` is ``p@ss``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from urllib.parse import unquote, urlsplit

SCHEMES = {"mqtt": (1883, False), "mqtts": (8883, True)}


@dataclass(frozen=True)
class Broker:
    host: str
    port: int
    tls: bool
    username: str | None = None
    password: str | None = field(default=None, repr=False)

    @classmethod
    def parse(cls, url: str) -> Broker:
        """The broker of ``url``; ValueError naming what is wrong (never the password)."""
        try:
            parts = urlsplit(url)
            port = parts.port
        except ValueError:
            raise ValueError(
                "not a broker URL: write mqtt://[user:password@]host[:port] (or mqtts://)"
            ) from None
        scheme = parts.scheme.lower()
        if scheme not in SCHEMES:
            raise ValueError(f"the scheme must be mqtt:// or mqtts://, not {scheme or 'none'}")
        if not parts.hostname:
            raise ValueError("the broker URL names no host")
        if parts.path not in ("", "/") or parts.query or parts.fragment:
            raise ValueError("a broker URL has no path or query: mqtt://user:password@host:port")
        default_port, tls = SCHEMES[scheme]
        if port == 0:
            raise ValueError("port 0 is no broker's port")
        return cls(
            host=parts.hostname,
            port=port or default_port,
            tls=tls,
            username=None if parts.username is None else unquote(parts.username),
            password=None if parts.password is None else unquote(parts.password),
        )

    def __str__(self) -> str:
        """The address as shown (health, logs): scheme, user, host and port; no password."""
        user = f"{self.username}@" if self.username else ""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{'mqtts' if self.tls else 'mqtt'}://{user}{host}:{self.port}"
