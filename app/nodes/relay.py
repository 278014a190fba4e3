"""Any node serves the whole site: what another node holds, it asks that node for.

A camera's pictures (MJPEG streams, single frames) come from the node that runs it; a
snapshot's or clip's file from the node that made it (its row names the node), unless the
file is here too (a media folder the nodes share). The node asked answers as it would a
browser; this node passes the answer on as it comes: status, the headers that matter (type,
length, ranges, caching) and the body, streamed, never whole in memory.

Nodes know each other from the ``nodes`` table: each says there its address
(``VIGIL_NODE_URL``) and a ``relay_token`` it makes at every start. A relayed request shows
the asked node its token in ``X-Vigil-Relay``; that stands for the password where the site
has one (``app.api.security.AccessControl``). A relayed request is never relayed again: a
node that no longer holds what was asked says so (404) instead of asking further.
"""

from __future__ import annotations

import contextlib
import json
import logging
import threading
import time
from collections.abc import AsyncIterator
from dataclasses import dataclass
from typing import Any

import httpx
from fastapi import HTTPException
from sqlalchemy import select
from starlette.background import BackgroundTask
from starlette.concurrency import run_in_threadpool
from starlette.requests import HTTPConnection
from starlette.responses import Response, StreamingResponse

from app.nodes.leases import DatabaseNow
from app.storage.db import Database
from app.storage.engine import reader
from app.storage.schema import nodes

log = logging.getLogger("vigil.nodes")

RELAY_HEADER = "x-vigil-relay"
PEERS_TTL_S = 2.0
"""How long the nodes table, as read, stands for it: a page polling frames costs no query
each, and a node that moved or died is seen within this."""
CONNECT_S = 3.0
FILE_READ_S = 30.0
"""Longest wait for the next part of a file's answer (a stream may wait for ever)."""
STATUS_READ_S = 3.0
"""Longest wait for a node's listing of its cameras (a listing here waits for it)."""
PASSED_ON = (
    "content-type",
    "content-length",
    "content-range",
    "content-disposition",
    "content-encoding",
    "accept-ranges",
    "cache-control",
    "pragma",
    "etag",
    "last-modified",
)
"""The asked node's response headers this one passes on."""
ASKED_WITH = ("range", "if-range", "if-none-match", "if-modified-since", "accept")
"""The client's request headers passed on to the node asked."""


@dataclass(frozen=True)
class Peer:
    name: str
    url: str
    token: str
    alive: bool


class NotRelayableError(Exception):
    """What was asked is on a node that cannot be asked; the text says which and why."""


class Relay:
    """This node (``me``, with ``token``) asking the others of its site in ``db``."""

    def __init__(self, db: Database, me: str, token: str, lease_s: float) -> None:
        self.db = db
        self.me = me
        self.token = token
        self.lease_s = lease_s
        self._lock = threading.Lock()
        self._peers: dict[str, Peer] = {}
        self._read_at = -PEERS_TTL_S
        self._client: httpx.AsyncClient | None = None
        self._fetcher = httpx.Client(follow_redirects=False, trust_env=False)
        """For whole small answers, from threads: one pool, not a connection a snapshot."""
        self._statuses: dict[str, tuple[float, dict[int, dict[str, Any]]]] = {}

    def peer(self, name: str) -> Peer:
        """The node ``name``, alive and not this one; NotRelayableError otherwise."""
        if name == self.me:
            raise NotRelayableError(f"node {name} is this one")
        with self._lock:
            if time.monotonic() - self._read_at > PEERS_TTL_S:
                self._peers = self._read_peers()
                self._read_at = time.monotonic()
            found = self._peers.get(name)
        if found is None or not found.alive or not found.url:
            raise NotRelayableError(f"node {name} is not running")
        return found

    def _read_peers(self) -> dict[str, Peer]:
        n = nodes.c
        with reader(self.db.engine).connect() as conn:
            clock = float(conn.execute(select(DatabaseNow())).scalar_one())
            rows = conn.execute(select(n.name, n.url, n.relay_token, n.renewed_at)).all()
        return {
            name: Peer(name, url.rstrip("/"), token, renewed >= clock - self.lease_s)
            for name, url, token, renewed in rows
        }

    def headers(self, peer: Peer) -> dict[str, str]:
        return {RELAY_HEADER: peer.token}

    @property
    def client(self) -> httpx.AsyncClient:
        if self._client is None:  # Made in the server's loop, at the first relay.
            self._client = httpx.AsyncClient(follow_redirects=False, trust_env=False)
        return self._client

    async def close(self) -> None:
        self._fetcher.close()
        if self._client is not None:
            await self._client.aclose()

    async def get(
        self, request: HTTPConnection, node: str, what: str, stream: bool = False
    ) -> Response:
        """``request`` (a GET) answered by ``node``, passed on as it comes. ``what`` names
        what was asked in errors; ``stream``: an endless answer (MJPEG), no read timeout.
        503 when the node is not running, 502 when it does not answer."""
        if is_relayed(request):
            raise HTTPException(404, f"{what} is not on this node")
        try:
            peer = await run_in_threadpool(self.peer, node)
        except NotRelayableError as why:
            raise HTTPException(503, f"{what} is on node {node}: {why}") from None
        url = peer.url + request.url.path + (f"?{request.url.query}" if request.url.query else "")
        headers = {k: v for k in ASKED_WITH if (v := request.headers.get(k)) is not None}
        timeout = httpx.Timeout(CONNECT_S, read=None if stream else FILE_READ_S)
        asked = self.client.build_request(
            "GET", url, headers={**headers, **self.headers(peer)}, timeout=timeout
        )
        try:
            answer = await self.client.send(asked, stream=True)
        except httpx.HTTPError as failed:
            raise HTTPException(
                502, f"{what} is on node {node} ({peer.url}), which does not answer: {failed}"
            ) from None
        passed = {k: v for k in PASSED_ON if (v := answer.headers.get(k)) is not None}
        return StreamingResponse(
            _body(answer),
            status_code=answer.status_code,
            headers=passed,
            # The body closes it at its end; this, when the client went first (the body
            # is then dropped unfinished).
            background=BackgroundTask(answer.aclose),
        )

    def statuses(self, node: str) -> dict[int, dict[str, Any]]:
        """The cameras ``node`` runs, as its ``GET /api/cameras`` shows them (state, reason,
        fps...), by id; read again after ``PEERS_TTL_S``. Empty when it does not answer."""
        with self._lock:
            read_at, known = self._statuses.get(node, (-PEERS_TTL_S, {}))
        if time.monotonic() - read_at <= PEERS_TTL_S:
            return known
        listed = self.fetch(node, "/api/cameras", STATUS_READ_S)
        try:
            rows = json.loads(listed) if listed is not None else []
            known = {r["id"]: r for r in rows if r.get("node") == node}
        except (ValueError, TypeError, KeyError, AttributeError):
            known = {}
        with self._lock:
            self._statuses[node] = (time.monotonic(), known)
        return known

    def fetch(self, node: str, path: str, timeout_s: float = FILE_READ_S) -> bytes | None:
        """A small answer (a snapshot) from ``node``, whole; None when it cannot be had."""
        try:
            peer = self.peer(node)
            answer = self._fetcher.get(
                peer.url + path,
                headers=self.headers(peer),
                timeout=httpx.Timeout(timeout_s, connect=CONNECT_S),
            )
        except (NotRelayableError, httpx.HTTPError) as failed:
            log.info("could not fetch %s from node %s: %s", path, node, failed)
            return None
        return answer.content if answer.status_code == 200 else None


async def _body(answer: httpx.Response) -> AsyncIterator[bytes]:
    """The asked node's body as it comes; a node that goes midway ends it (the client sees
    a short answer, as from a server that went)."""
    try:
        async for chunk in answer.aiter_raw():
            yield chunk
    except httpx.HTTPError as failed:
        log.info("relay from %s ended: %s", answer.url, failed)
    finally:
        with contextlib.suppress(Exception):
            await answer.aclose()


def is_relayed(request: HTTPConnection) -> bool:
    """Whether ``request`` comes from another node (never to be relayed on)."""
    return RELAY_HEADER in request.headers
