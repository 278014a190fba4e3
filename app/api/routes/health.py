from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request

from app.api.services import services

router = APIRouter()


@router.get("/api/health")
def health(request: Request) -> dict[str, Any]:
    """``status`` is ``ok`` while the server answers; ``storage``: are snapshots being saved;
    ``mqtt``: ``disabled``, or ``connected`` / ``disconnected`` (with the reason) to the
    broker. MQTT down is not the server down: ``status`` stays ``ok``."""
    svc = services(request)
    return {"status": "ok", "storage": svc.storage(), "mqtt": svc.mqtt_health()}
