"""The site's nodes (``GET /api/nodes``, docs/scaling.md)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request

from app.api.services import services

router = APIRouter()


@router.get("/api/nodes")
def list_nodes(request: Request) -> list[dict[str, Any]]:
    """Each node by name: its ``url``, the ``cameras`` it runs, ``renewed_at`` (its last
    renewal, UNIX time), ``load`` (cameras over capacity), ``capacity`` and ``alive``.
    Without a shared database, this node alone, with every camera."""
    return services(request).nodes()
