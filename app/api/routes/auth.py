"""Logging in and out: ``GET /login``, ``POST /api/login``, ``POST /api/logout``.

A form (the login page, the dashboard's Log out button) gets redirects and pages back;
JSON gets JSON. The session cookie is HttpOnly, SameSite=Strict, and Secure over https.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from urllib.parse import parse_qs

from fastapi import APIRouter, HTTPException, Request
from fastapi.responses import JSONResponse, RedirectResponse, Response

import app as vigil_package
from app.api.routes.pages import TEMPLATES
from app.api.security import (
    SESSION_COOKIE,
    Access,
    ThrottledError,
    client_address,
    local_path,
    too_many_attempts,
)

router = APIRouter(tags=["auth"])
FORM = "application/x-www-form-urlencoded"
MAX_LOGIN_BODY = 8192
"""A login is a password and a path: anything bigger is not one (the route is open to all,
so ``BodyLimit`` refuses more)."""


@dataclass
class Credentials:
    password: str
    next: str
    from_form: bool


def _access(request: Request) -> Access | None:
    access: Access | None = request.app.state.access
    return access


def _content_type(request: Request) -> str:
    return request.headers.get("content-type", "").split(";")[0].strip().lower()


def _is_form(request: Request) -> bool:
    return _content_type(request) == FORM


def _page(
    request: Request,
    next_path: str,
    error: str = "",
    status: int = 200,
    headers: dict[str, str] | None = None,
) -> Response:
    return TEMPLATES.TemplateResponse(
        request,
        "login.html",
        {"version": vigil_package.__version__, "next": next_path, "error": error},
        status_code=status,
        headers=headers,
    )


@router.get("/login", include_in_schema=False)
async def login_page(request: Request, next: str = "/") -> Response:  # on the loop, like Sessions
    access = _access(request)
    token = request.cookies.get(SESSION_COOKIE)
    if access is None or (token and access.sessions.touch(token)):
        return RedirectResponse(local_path(next), status_code=303)
    return _page(request, local_path(next))


async def _credentials(request: Request) -> Credentials:
    body = await request.body()  # At most MAX_LOGIN_BODY: BodyLimit sees to it.
    if _is_form(request):
        fields = parse_qs(body.decode("utf-8", "replace"), keep_blank_values=True)
        return Credentials(
            fields.get("password", [""])[0], local_path(fields.get("next", ["/"])[0]), True
        )
    if _content_type(request) != "application/json":
        raise HTTPException(415, 'send the password as a form field or as JSON {"password": ...}')
    try:
        data = json.loads(body)
    except ValueError:
        data = None
    if not isinstance(data, dict) or not isinstance(data.get("password"), str):
        raise HTTPException(422, 'send JSON {"password": "..."}')
    unknown = sorted(set(data) - {"password"})
    if unknown:  # As every JSON body: a field that means nothing here is a mistake.
        raise HTTPException(422, f'unknown field {unknown[0]!r}: send JSON {{"password": "..."}}')
    return Credentials(data["password"], "/", False)


@router.post("/api/login")
async def login(request: Request) -> Response:
    """Form field or JSON ``password``; sets the session cookie. 429 after too many wrong ones."""
    access = _access(request)
    if access is None:
        raise HTTPException(404, "no password is set: there is nothing to log in to")
    credentials = await _credentials(request)
    try:
        ok = await access.verify(client_address(request), credentials.password)
    except ThrottledError as throttled:
        if credentials.from_form:
            detail = f"Too many wrong passwords: try again in {throttled.retry_after} s."
            retry = {"Retry-After": str(throttled.retry_after)}
            return _page(request, credentials.next, detail, 429, retry)
        return too_many_attempts(throttled)
    if not ok:
        if credentials.from_form:
            return _page(request, credentials.next, "Wrong password.", 401)
        return JSONResponse({"detail": "wrong password"}, status_code=401)
    response: Response = (
        RedirectResponse(credentials.next, status_code=303)
        if credentials.from_form
        else JSONResponse({"status": "logged in"})
    )
    response.set_cookie(
        SESSION_COOKIE,
        access.sessions.create(),
        path="/",
        httponly=True,
        samesite="strict",
        secure=request.url.scheme == "https",
    )
    return response


@router.post("/api/logout")
async def logout(request: Request) -> Response:
    """Ends the session and clears its cookie: a form goes on to /login, anything else gets 204."""
    access = _access(request)
    token = request.cookies.get(SESSION_COOKIE)
    if access is not None and token:
        access.sessions.end(token)
    response = (
        RedirectResponse("/login", status_code=303)
        if _is_form(request)
        else Response(status_code=204)
    )
    response.delete_cookie(
        SESSION_COOKIE,
        path="/",
        httponly=True,
        samesite="strict",
        secure=request.url.scheme == "https",
    )
    return response
