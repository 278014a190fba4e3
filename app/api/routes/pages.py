"""The dashboard page."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import FileResponse, HTMLResponse
from fastapi.templating import Jinja2Templates

import app as vigil_package
from app.api.routes.inputs import MAX_MIN_AREA
from app.api.services import services
from app.core.paths import STATIC_DIR, TEMPLATES_DIR
from app.vision.motion import DEFAULT_METHOD, METHODS

router = APIRouter()
TEMPLATES = Jinja2Templates(directory=str(TEMPLATES_DIR))
FAVICON = STATIC_DIR / "favicon.svg"


@router.get("/", response_class=HTMLResponse, include_in_schema=False)
def dashboard(request: Request) -> HTMLResponse:
    svc = services(request)
    return TEMPLATES.TemplateResponse(
        request,
        "index.html",
        {
            "version": vigil_package.__version__,
            "methods": list(METHODS),
            "default_method": DEFAULT_METHOD,
            "max_upload_mb": svc.settings.max_upload_mb,
            "max_min_area": MAX_MIN_AREA,
        },
    )


@router.get("/favicon.ico", include_in_schema=False)
def favicon() -> FileResponse:
    """The icon for pages that name none (a JSON answer, the API docs): the SVG one."""
    return FileResponse(
        FAVICON, media_type="image/svg+xml", headers={"Cache-Control": "max-age=86400"}
    )
