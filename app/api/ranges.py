"""A file answered in part when asked (HTTP Range requests), so a browser can seek in a video.

``FileResponse`` does this for a finished file, but reads to the end of the file whatever
length it announced: a clip still being recorded grows meanwhile, and would be sent
longer than its ``Content-Length``. Here the length is given, and exactly that many
bytes are read. One range per request (what browsers ask for a video); a request for
several, or a ``Range`` that does not parse, gets the whole file (RFC 9110 lets a server
ignore it), and one that starts past the end gets 416 with the length.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

from fastapi import HTTPException, Request, Response
from fastapi.responses import StreamingResponse

CHUNK = 1 << 16
RANGE = re.compile(r"bytes=(\d*)-(\d*)")


def _wanted(header: str, size: int) -> tuple[int, int] | bool | None:
    """(first, last) byte of the one range asked for; None: serve it all; False: none of it
    is there (416)."""
    match = RANGE.fullmatch(header.strip().replace(" ", ""))
    if match is None:
        return None  # Several ranges, another unit, or not a range at all.
    first, last = match[1], match[2]
    if not first:
        if not last:
            return None
        suffix = int(last)
        if suffix == 0 or size == 0:
            return False
        return max(0, size - suffix), size - 1
    start = int(first)
    end = int(last) if last else size - 1
    if last and end < start:
        return None
    if start >= size:
        return False
    return start, min(end, size - 1)


def _read(path: Path, start: int, count: int) -> Iterator[bytes]:
    with path.open("rb") as handle:
        handle.seek(start)
        while count > 0:
            block = handle.read(min(CHUNK, count))
            if not block:
                return
            count -= len(block)
            yield block


def ranged_file(
    request: Request,
    path: Path,
    media_type: str,
    length: int | None = None,
    filename: str | None = None,
    cache: str = "no-cache",
) -> Response:
    """``path``'s first ``length`` bytes (default: all of it), whole or the range asked for.
    404 when the file is not there."""
    try:
        stat = path.stat()
    except OSError:
        raise HTTPException(404, f"{path.name} is not there") from None
    size = stat.st_size if length is None else min(length, stat.st_size)
    etag = f'"{stat.st_mtime_ns:x}-{size:x}"'
    headers = {"Accept-Ranges": "bytes", "ETag": etag, "Cache-Control": cache}
    if filename:
        headers["Content-Disposition"] = f'inline; filename="{filename}"'
    asked = request.headers.get("range")
    if_range = request.headers.get("if-range")
    wanted = _wanted(asked, size) if asked and if_range in (None, etag) else None
    if wanted is False:
        return Response(status_code=416, headers={**headers, "Content-Range": f"bytes */{size}"})
    status = 200
    start, end = 0, size - 1
    if isinstance(wanted, tuple):
        status = 206
        start, end = wanted
        headers["Content-Range"] = f"bytes {start}-{end}/{size}"
    count = max(0, end - start + 1)
    headers["Content-Length"] = str(count)
    return StreamingResponse(
        _read(path, start, count), status_code=status, media_type=media_type, headers=headers
    )
