"""What the routers accept: ids SQLite can hold, names without control characters, and
JSON bodies without NaN or Infinity.

Python's json module reads ``NaN`` and ``Infinity``, which are not JSON, and turns
``1e999`` into infinity. A body holding one was refused with a 422 whose echo of the input
could not itself be written as JSON, so the client got a 500 instead. Routers built
with ``route_class=StrictJsonRoute`` refuse such a body as malformed JSON. A 422's echo
of the input has URL passwords masked (``validation_error``).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Coroutine
from typing import Annotated, Any

from fastapi import Query, Request, Response
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from fastapi.routing import APIRoute
from pydantic import ConfigDict

from app.sources.live import without_password

MAX_ID = 2**63 - 1
"""SQLite's largest integer: a larger id names nothing (and SQLite refuses to bind it)."""
MAX_IDS = 100_000
"""Ids in one request: SQLite binds at most 250,000 parameters in one statement."""

CameraFilter = Annotated[int | None, Query(ge=0, le=MAX_ID)]
"""``camera_id`` in a listing's filters."""
TimeFilter = Annotated[float | None, Query(allow_inf_nan=False)]
"""``since`` and ``until``: Unix seconds, finite."""
STRICT = ConfigDict(extra="forbid", strict=True)
"""Every JSON body's model: a misspelt field is an error, not ignored; and a value must be
of its field's JSON type, not coerced: ``"10"`` or ``true`` is no sensitivity, ``"yes"`` or
``1`` no ``show_mask``, ``"1"`` no snapshot id. A whole number is a number (``10`` for
``10.0``)."""
MAX_MIN_AREA = 7680 * 4320
"""The largest ``min_area``: an 8K frame's pixels (33,177,600). An object must cover at
least ``min_area`` pixels of the input frame, so a larger value can never be met and
would quietly turn detection off."""


def check_min_area(value: float | None) -> float | None:
    """``min_area`` at most ``MAX_MIN_AREA``: more than any frame holds is no setting."""
    if value is not None and value > MAX_MIN_AREA:
        raise ValueError(
            f"min_area is at most {MAX_MIN_AREA:,} pixels (an 8K frame, 7680x4320): a larger"
            " one no object could cover, and detection would be off"
        )
    return value


def is_control(char: str) -> bool:
    """C0 and C1 control characters (NUL, newline, escape...): never part of a name."""
    return ord(char) < 32 or 127 <= ord(char) < 160


def _refuse_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{text} is too large a number")
    return value


def strict_json(raw: bytes) -> Any:
    """``json.loads`` that takes only numbers JSON and the API can represent."""
    try:
        return json.loads(raw, parse_constant=_refuse_constant, parse_float=_finite_float)
    except json.JSONDecodeError:
        raise
    except ValueError as exc:  # Ours, bad UTF-8, integers past Python's digit limit.
        raise json.JSONDecodeError(str(exc), raw.decode(errors="replace"), 0) from None


class _StrictJsonRequest(Request):
    async def json(self) -> Any:
        if not hasattr(self, "_json"):
            self._json = strict_json(await self.body())
        return self._json


class StrictJsonRoute(APIRoute):
    """A route whose JSON body is read by ``strict_json`` (FastAPI's own 422 when it fails)."""

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()

        async def strict_handler(request: Request) -> Response:
            return await handler(_StrictJsonRequest(request.scope, request.receive))

        return strict_handler


ECHO_LIMIT = 200
"""Characters of a refused value echoed back in a 422: enough to recognise it, where a
file sent as a plain form field (a part with no file name) would come back whole."""

NOT_A_FILE = "Expected UploadFile"
"""What FastAPI's message says when a file parameter got a plain form field."""


VALUE_ERROR = "Value error, "
"""What pydantic puts before the message of a ValueError that a check raised."""


async def validation_error(request: Request, exc: Exception) -> JSONResponse:
    """FastAPI's 422, with every URL password in the echoed input masked (a refused
    camera source must not carry its password back to logs, proxies, browser tools),
    long inputs cut to ``ECHO_LIMIT`` characters, a file sent without a file name
    said so, and our own checks' messages without pydantic's "Value error, "."""
    assert isinstance(exc, RequestValidationError)  # What it is registered for.
    # A body that is no JSON is echoed as bytes, which need not be UTF-8.
    as_text = {bytes: lambda data: data.decode("utf-8", "replace")}
    errors = _masked(jsonable_encoder(exc.errors(), custom_encoder=as_text))
    for error in errors:
        message = str(error.get("msg", ""))
        if NOT_A_FILE in message:
            error["msg"] = "expected a file: a multipart part with a file name"
        elif message.startswith(VALUE_ERROR):  # Our own checks' words, as they are.
            error["msg"] = message.removeprefix(VALUE_ERROR)
        echoed = error.get("input")
        if isinstance(echoed, str) and len(echoed) > ECHO_LIMIT:
            error["input"] = f"{echoed[:ECHO_LIMIT]}... ({len(echoed):,} characters)"
    return JSONResponse(status_code=422, content={"detail": errors})


def _masked(value: Any) -> Any:
    if isinstance(value, str):
        return without_password(value)
    if isinstance(value, dict):
        return {key: _masked(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_masked(item) for item in value]
    return value
