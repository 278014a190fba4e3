from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request

from app.api.services import services

router = APIRouter()


@router.get("/api/health")
def health(request: Request) -> dict[str, Any]:
    """``status`` is ``ok`` while the server answers; ``storage``: are snapshots being saved."""
    return {"status": "ok", "storage": services(request).storage()}
