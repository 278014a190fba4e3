"""Live sources for the dashboard's cameras: demo, device, RTSP, HTTP MJPEG, looped file
or folder of images.

A source is opened, read frame by frame and closed by one worker thread. A
failure to open or a lost stream is a ``SourceError`` with a readable reason;
the worker retries with backoff. ``paced`` sources (the demo scene, a file, a folder)
would deliver frames as fast as they decode, so the worker paces them at
``fps``; live sources deliver at their own rate. Where a stream is MJPEG,
FFmpeg hands over the camera's own JPEGs, decoded later only as far as needed
(``app.sources.frames``).
"""

from __future__ import annotations

import base64
import http.client
import re
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, Protocol
from urllib.parse import unquote, urlparse

import cv2
import numpy as np

from app.sources.demo_scene import StreetScene, demo_street_scene
from app.sources.files import DEFAULT_FPS, InputError, frame_rate, list_images, open_input
from app.sources.frames import DecodedFrame, FrameError, JpegFrame, SourceFrame
from app.sources.synthetic import Scene

SourceKind = Literal["demo", "device", "rtsp", "http", "file"]


class SourceError(RuntimeError):
    """A source that cannot be opened or was lost; the message says why, in one line."""


@dataclass(frozen=True)
class SourceSpec:
    kind: SourceKind
    target: str
    """What is opened: the device index or path, the URL, or the file's path."""
    raw: str


EXIF = b"Exif\x00\x00"
"""The start of a JPEG's EXIF segment (APP1), which may say to turn the picture."""
EXIF_REACH = 4096
"""Bytes from a JPEG's start in which an EXIF segment is sought: it comes first, or after
a JFIF one."""

MAX_DEVICE_INDEX = 999
"""The largest device index a source may name (three digits, as V4L2 numbers go)."""


def parse_source(text: str) -> SourceSpec:
    """Parse what a person typed; raises ValueError with the reason when it is not a source."""
    raw = text.strip()
    if not raw:
        raise ValueError("source is empty")
    lowered = raw.lower()
    if lowered == "demo":
        return SourceSpec("demo", "demo", raw)
    if re.fullmatch(r"[+-]?\d+", raw):
        # A number is a device index (V4L2 /dev/videoN), never a file's name: a file
        # named so is written ./5 or file://5.
        if raw[0] in "+-" or len(raw) > len(str(MAX_DEVICE_INDEX)):
            raise ValueError(
                f"a device index is a whole number from 0 to {MAX_DEVICE_INDEX}, not {raw}"
                " (the first camera is 0)"
            )
        return SourceSpec("device", raw, raw)
    if lowered.startswith(("rtsp://", "rtsps://", "http://", "https://")):
        url = urlparse(raw)
        if not url.hostname:
            raise ValueError(f"URL has no host: {without_password(raw)}")
        try:
            port_ok = url.port != 0  # None (the scheme's own) or 1..65535.
        except ValueError:  # Past 65535, or not a number.
            port_ok = False
        if not port_ok:
            raise ValueError(f"URL port is not 1..65535: {without_password(raw)}")
        return SourceSpec("rtsp" if lowered.startswith("rtsp") else "http", raw, raw)
    if lowered.startswith("file://"):
        parsed = urlparse(raw)
        path = unquote(parsed.path)
        if parsed.netloc and parsed.netloc != "localhost":
            path = unquote(parsed.netloc + parsed.path)  # file://relative/x.avi
        if not path:
            raise ValueError(f"file URL has no path: {raw}")
        return SourceSpec("file", path, raw)
    if raw.startswith("/dev/"):
        return SourceSpec("device", raw, raw)
    if "://" in raw:
        raise ValueError(f"unsupported source scheme: {raw.split('://', 1)[0]}")
    return SourceSpec("file", raw, raw)


MASK = "***"
"""What logs and the API show in place of a source's password (``without_password``)."""

SECRET_PARAMS = (
    "password",
    "passwd",
    "pass",
    "pwd",
    "pswd",
    "psw",
    "pw",
    "loginpas",
    "token",
    "auth",
)
"""Parameters that carry a camera's password, in its query (``/video.cgi?user=admin&pwd=``)
or its path (``rtsp://dvr/user=admin&password=...&channel=1.sdp``)."""
USER_PARAMS = ("user", "usr", "username", "loginuse")
"""Parameters that name the user a password parameter belongs to."""

_URL = re.compile(
    r"(?P<scheme>[A-Za-z][A-Za-z0-9+.-]*://)(?P<authority>[^/?#]*)(?P<path>[^?#]*)"
    r"(?P<query>\?[^#]*)?(?P<fragment>#.*)?",
    re.DOTALL,
)
"""A URL cut where ``urllib.parse.urlsplit`` cuts it (and FFmpeg: the authority ends at the
first ``/``, ``?`` or ``#``), so that putting the parts together gives the text back."""
_PARAM = r"(?P<head>[/?&;](?P<name>{})=)(?P<value>[^/?&;#]*)"
_SECRET_PARAM = re.compile(_PARAM.format("|".join(SECRET_PARAMS)), re.IGNORECASE)
_USER_PARAM = re.compile(_PARAM.format("|".join(USER_PARAMS)), re.IGNORECASE)


def _edit_passwords(text: str, edit: Callable[[str, str], str]) -> str:
    """``text`` with each password in it replaced by ``edit(place, password)``.

    A password is the one of the URL's user information (``scheme://user:password@host``,
    ``place`` ``"userinfo"``; split at the last ``@`` and the first ``:``) or the value of
    a parameter named in ``SECRET_PARAMS``, in the path or the query (``place`` ``"?"``
    and its name in lower case). Everything else, and any text that is not a URL, stays
    as it is, character for character.
    """
    url = _URL.fullmatch(text)
    if url is None:
        return text
    authority = url["authority"]
    userinfo, at, host = authority.rpartition("@")
    if at and ":" in userinfo:
        user, _, password = userinfo.partition(":")
        authority = f"{user}:{edit('userinfo', password)}@{host}"
    rest = _SECRET_PARAM.sub(
        lambda m: m["head"] + edit("?" + m["name"].lower(), m["value"]),
        url["path"] + (url["query"] or ""),
    )
    return url["scheme"] + authority + rest + (url["fragment"] or "")


def _passwords(text: str) -> list[tuple[str, str]]:
    """Where ``text`` holds a password, and the password, in order (see ``_edit_passwords``)."""
    found: list[tuple[str, str]] = []

    def note(place: str, password: str) -> str:
        found.append((place, password))
        return password

    _edit_passwords(text, note)
    return found


def _endpoint(text: str) -> tuple[str, str, str, list[tuple[str, str]]] | None:
    """Whom a URL's password goes to: its scheme, user, host with port, and the users its
    parameters name (None: not a URL)."""
    url = _URL.fullmatch(text)
    if url is None:
        return None
    userinfo, _, host = url["authority"].rpartition("@")
    users = [
        (m["name"].lower(), m["value"])
        for m in _USER_PARAM.finditer(url["path"] + (url["query"] or ""))
    ]
    return url["scheme"].lower(), userinfo.partition(":")[0], host.lower(), users


def without_password(text: str) -> str:
    """``text`` with its passwords replaced by ``MASK``: a source as logs and the API show it.

    ``rtsp://admin:secret@10.0.0.5/stream`` gives ``rtsp://admin:***@10.0.0.5/stream`` (the
    user is kept), ``http://cam/video.cgi?user=admin&pwd=secret`` gives ``...&pwd=***``,
    ``rtsp://dvr/user=admin&password=secret&channel=1.sdp`` ``...&password=***&...``;
    a source without a password (``demo``, ``0``, ``/dev/video0``, ``file:///x.avi``,
    ``rtsp://admin@cam/live``) comes back unchanged.
    """
    return _edit_passwords(text, lambda place, password: MASK)


def has_masked_password(text: str) -> bool:
    """Whether a password in ``text`` reads ``MASK``: a source copied as the API shows it."""
    return bool(_masked_places(text))


def _masked_places(text: str) -> set[str]:
    return {place for place, password in _passwords(text) if password == MASK}


def with_stored_password(source: str, stored: str) -> str:
    """The source to keep when ``source`` is sent for a camera whose source is ``stored``.

    The API shows ``without_password(stored)``, so a form or a script sends back what
    it was shown, and that must not replace the password with ``MASK``:

    - ``source`` is ``without_password(stored)`` (or ``stored``): ``stored``, unchanged.
    - No password in ``source`` reads ``MASK``: a new source, taken as it is.
    - A password reads ``MASK`` and the rest changed (another stream path, say): the
      stored password is put back in its place, if ``source`` goes to the same scheme,
      user (of ``user:password@`` and of ``USER_PARAMS``), host and port as ``stored``
      and ``stored`` has a password in that place. A password is never sent to another
      server than the one it was given for, so moving a camera to another address means
      typing its password.
    - Otherwise ``ValueError`` saying why (without the password).

    A password that really is ``***`` is written percent-encoded: ``%2A%2A%2A``.
    """
    shown = without_password(stored)
    if source in (stored, shown):
        return stored
    masked = _masked_places(source)
    if not masked:
        return source
    if _endpoint(source) != _endpoint(stored):
        raise ValueError(
            f"{MASK} stands for the stored password, which goes only to the scheme, user, "
            f"host and port it was given for ({shown}): type the password for this source"
        )
    known: dict[str, str] = {}
    for place, password in _passwords(stored):
        known.setdefault(place, password)
    if not masked <= known.keys():
        raise ValueError(
            f"{MASK} stands for a stored password, but the camera's source ({shown}) has "
            "none in that place: type the password"
        )
    return _edit_passwords(
        source, lambda place, password: known[place] if password == MASK else password
    )


def why_not_open(url: str, timeout_ms: int) -> str:
    """Why a network camera did not open, as far as asking it again can tell (FFmpeg
    says nothing through OpenCV): ``": ..."`` to append to the reason, or ``""``.

    An http camera is asked for the stream the way FFmpeg asks (basic auth from the URL):
    a refused login, another HTTP status or an answer that is not a picture stream is
    named. For other schemes, whether the port refuses or does not answer. Never the
    password: only the status, the content type or the socket's error.
    """
    parsed = urlparse(url)
    try:
        port = parsed.port or {"http": 80, "https": 443, "rtsp": 554}.get(parsed.scheme.lower())
    except ValueError:
        return ""
    if not parsed.hostname or port is None:
        return ""
    timeout_s = timeout_ms / 1000
    if parsed.scheme.lower() != "http":
        try:
            socket.create_connection((parsed.hostname, port), timeout_s).close()
        except OSError as exc:
            return f": {_socket_error(exc, port)}"
        return ""
    path = (parsed.path or "/") + (f"?{parsed.query}" if parsed.query else "")
    headers = {}
    if parsed.username is not None:
        login = f"{unquote(parsed.username)}:{unquote(parsed.password or '')}"
        headers["Authorization"] = "Basic " + base64.b64encode(login.encode()).decode()
    connection = http.client.HTTPConnection(parsed.hostname, port, timeout=timeout_s)
    try:
        connection.request("GET", path, headers=headers)
        answer = connection.getresponse()
        status, why, kind = answer.status, answer.reason, answer.getheader("Content-Type", "")
    except OSError as exc:
        return f": {_socket_error(exc, port)}"
    except http.client.HTTPException:
        return ": it does not answer as an http server"
    finally:
        connection.close()
    if status in (401, 403):
        return f": it refused the user and password (HTTP {status})"
    if status >= 300:
        return f": it answered HTTP {status} {why}"
    kind = kind.split(";")[0].strip().lower()
    if kind.startswith(("multipart/", "image/")):
        return ""
    return f": it answered with {kind or 'no content type'}, not a picture stream"


def _socket_error(error: OSError, port: int) -> str:
    if isinstance(error, ConnectionRefusedError):
        return f"nothing listens on port {port}"
    if isinstance(error, TimeoutError):
        return "no answer"
    return str(error)


class FrameSource(Protocol):
    fps: float
    paced: bool
    description: str

    def read(self) -> SourceFrame:
        """The next frame; SourceError when the source is lost, FrameError for one bad frame."""
        ...

    def close(self) -> None: ...


def open_source(
    spec: SourceSpec, open_timeout_ms: int = 3000, read_timeout_ms: int = 2000
) -> FrameSource:
    """Open a source or raise SourceError with the reason."""
    if spec.kind == "demo":
        return DemoSource()
    if spec.kind == "file":
        path = Path(spec.target)
        return FolderSource(path) if path.is_dir() else FileSource(path)
    if spec.kind == "device":
        return CaptureSource.device(spec.target)
    return CaptureSource.network(spec.target, open_timeout_ms, read_timeout_ms)


def demo_scene() -> StreetScene:
    """The demo camera's scene: a street where people walk by and cars pass, a quiet gap
    of more than two seconds between each (``app.sources.demo_scene``), so an activated
    demo camera gives a new alarm (and snapshot) for each."""
    return demo_street_scene()


class DemoSource:
    """The synthetic demo scene, looped forever. The street is painted once per process
    (about half a second) and each pose of a passer-by once, when first needed; a frame is
    then a copy of the street with sprites pasted on (``bench/bench_demo_scene.py``)."""

    paced = True

    def __init__(self, scene: Scene | StreetScene | None = None) -> None:
        self.scene = scene or demo_scene()
        self.fps = self.scene.fps
        self.description = f"demo scene {self.scene.size[0]}x{self.scene.size[1]}"
        self._index = 0

    def read(self) -> SourceFrame:
        frame = self.scene.frame(self._index % self.scene.frames)
        self._index += 1
        return DecodedFrame(frame)

    def close(self) -> None:
        pass


class FolderSource:
    """A folder of images (JPEG, PNG, ...), looped in name order (2 before 10) at
    ``DEFAULT_FPS``, as ``vigil analyze`` reads one. A CDnet sequence's folder gives the
    frames of its ``input/``.

    The folder is listed again at the start of each loop, so pictures added meanwhile
    (a camera that drops JPEGs into it) are shown on the next. Each picture is a frame
    as it is, whatever its size (a camera whose resolution was changed goes on; the
    detector learns the new view). One that cannot be read or decoded is a bad frame
    (``FrameError``).
    """

    paced = True

    def __init__(self, path: Path) -> None:
        try:
            found = open_input(path)  # Checks that two of its pictures decode.
        except InputError as exc:
            raise SourceError(str(exc)) from None
        assert found.images is not None  # A folder's input.
        self._folder = found.path
        """The folder that holds the frames (a CDnet sequence's ``input/``)."""
        self._images = found.images
        self._next = 0
        self.fps = DEFAULT_FPS
        self.description = f"folder {path.name}: {len(self._images)} images at {self.fps:g} fps"

    def read(self) -> SourceFrame:
        if self._next >= len(self._images):  # A new loop, of the folder as it is now.
            try:
                self._images, self._next = list_images(self._folder), 0
            except (InputError, OSError) as exc:
                raise SourceError(f"folder {self._folder.name}: {exc}") from None
            if not self._images:
                raise SourceError(f"no image frames in folder: {self._folder}")
        image_path = self._images[self._next]
        self._next += 1
        try:
            data = image_path.read_bytes()
        except OSError as exc:  # Removed since the folder was listed, say.
            raise FrameError(f"{image_path.name} cannot be read: {exc.strerror}") from None
        if data[:2] == b"\xff\xd8" and EXIF not in data[:EXIF_REACH]:
            # A JPEG stays one, decoded only as far as someone needs it, as a camera's.
            return JpegFrame(data)
        # Other kinds, and a JPEG with EXIF, which may turn it (phone pictures): upright,
        # as ``vigil analyze`` reads it.
        image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
        if image is None:
            raise FrameError(f"{image_path.name} does not decode as a picture")
        return DecodedFrame(image)

    def close(self) -> None:
        pass


class FileSource:
    """A video file looped at its own frame rate."""

    paced = True

    def __init__(self, path: Path) -> None:
        self.path = path
        self._capture = self._open()
        self.fps = frame_rate(self._capture)
        self.description = f"file {path.name} at {self.fps:g} fps"
        self._frames_in_loop = 0

    def _open(self) -> cv2.VideoCapture:
        """Opened at the start and again at each loop: the file may be gone by then."""
        if not self.path.is_file():
            raise SourceError(f"file not found: {self.path}")
        capture = cv2.VideoCapture(str(self.path), cv2.CAP_FFMPEG)
        if not capture.isOpened():
            capture.release()
            raise SourceError(f"not a video FFmpeg can decode: {self.path.name}")
        self._packets = jpeg_packets(capture)
        return capture

    def read(self) -> SourceFrame:
        ok, frame = self._capture.read()
        if ok and frame is not None:
            self._frames_in_loop += 1
            return as_frame(frame, self._packets)
        if self._frames_in_loop == 0:
            raise SourceError(f"no decodable frames in {self.path.name}")
        self._capture.release()  # End of file: start again.
        self._capture = self._open()
        self._frames_in_loop = 0
        ok, frame = self._capture.read()
        if not ok or frame is None:
            raise SourceError(f"no decodable frames in {self.path.name}")
        self._frames_in_loop = 1
        return as_frame(frame, self._packets)

    def close(self) -> None:
        self._capture.release()


class CaptureSource:
    """A device, RTSP or HTTP MJPEG camera through OpenCV's capture."""

    paced = False

    def __init__(self, capture: cv2.VideoCapture, description: str, packets: bool) -> None:
        self._capture = capture
        self._packets = packets
        self.fps = frame_rate(capture)
        self.description = description

    @classmethod
    def device(cls, target: str) -> CaptureSource:
        capture = cv2.VideoCapture(int(target)) if target.isdigit() else cv2.VideoCapture(target)
        if not capture.isOpened():
            capture.release()
            raise SourceError(f"no camera at {'index ' + target if target.isdigit() else target}")
        return cls(capture, f"device {target}", packets=False)

    @classmethod
    def network(cls, url: str, open_timeout_ms: int, read_timeout_ms: int) -> CaptureSource:
        # Timeouts, or a stalled server blocks read() for 30 s.
        params = [
            cv2.CAP_PROP_OPEN_TIMEOUT_MSEC,
            open_timeout_ms,
            cv2.CAP_PROP_READ_TIMEOUT_MSEC,
            read_timeout_ms,
        ]
        started = time.monotonic()
        capture = cv2.VideoCapture(url, cv2.CAP_FFMPEG, params)
        parsed = urlparse(url)
        host = parsed.hostname or without_password(url)
        if not capture.isOpened():
            capture.release()
            # A camera that let the open time out would let a second question time out too.
            timed_out = time.monotonic() - started >= 0.9 * open_timeout_ms / 1000
            why = ": no answer" if timed_out else why_not_open(url, open_timeout_ms)
            raise SourceError(f"cannot open stream from {host}{why}")
        packets = jpeg_packets(capture)
        return cls(capture, f"{parsed.scheme} stream from {host}", packets)

    def read(self) -> SourceFrame:
        ok, frame = self._capture.read()
        if not ok or frame is None:
            raise SourceError("stream lost")
        return as_frame(frame, self._packets)

    def close(self) -> None:
        self._capture.release()


JPEG_FOURCCS = frozenset({b"MJPG", b"JPEG", b"AVRN", b"LJPG", b"DMB1"})


def jpeg_packets(capture: cv2.VideoCapture) -> bool:
    """Switch an MJPEG stream to handing over its JPEGs undecoded; True when it did."""
    fourcc = int(capture.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little").upper()
    return fourcc in JPEG_FOURCCS and bool(capture.set(cv2.CAP_PROP_FORMAT, -1))


def as_frame(data: np.ndarray, packet: bool) -> SourceFrame:
    """What ``VideoCapture.read`` gave: a JPEG packet (FrameError if it is not one) or pixels."""
    return JpegFrame(data.tobytes()) if packet else DecodedFrame(data)
