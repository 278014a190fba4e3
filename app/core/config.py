"""Settings in one place: defaults, overridden by ``VIGIL_*`` environment variables."""

from __future__ import annotations

import os
import socket
from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

MAX_PORT = 65535
CAMERAS_PER_CORE = 20
"""A node's capacity by default: one machine of two cores carries about 45 activated
cameras (bench/bench_cameras.py)."""


class Settings(BaseSettings):
    """What ``vigil serve`` runs with (``VIGIL_PORT=9000``, ``VIGIL_DATA_DIR=/srv/vigil``...)."""

    model_config = SettingsConfigDict(env_prefix="VIGIL_", extra="ignore")

    host: str = "127.0.0.1"
    port: int = Field(default=8000, ge=1, le=MAX_PORT)
    data_dir: Path = Path("data")
    """Holds vigil.db (SQLite), snapshots/, clips/ and analyses/."""
    media_dir: Path | None = None
    """Holds snapshots/, clips/ and analyses/ instead of ``data_dir``: a folder every node
    of a site reaches (NFS), so each serves every file from there (docs/scaling.md)."""
    database_url: str | None = Field(default=None, repr=False)
    """PostgreSQL instead of SQLite for every table: ``postgresql://user:password@host:5432/
    database`` (special characters of the password %-encoded; libpq's parameters such as
    ``?sslmode=require`` may follow). Unset or empty: SQLite, ``vigil.db`` in the data
    folder. Its password is never shown."""
    password: str | None = Field(default=None, repr=False)
    """When set, every page and API call needs a login (``/login``) or HTTP basic auth with
    this password. The app keeps only its scrypt hash."""
    password_hash: str | None = Field(default=None, repr=False)
    """The password as ``vigil hash-password`` prints it (``scrypt:N:r:p:salt:key``, hex), so
    the plain password need not be in the environment. Set this or ``password``, not both."""
    session_hours: float = Field(default=12.0, gt=0)
    """A login session ends after this many hours without a request."""
    login_max_failures: int = Field(default=5, ge=1)
    """Wrong passwords allowed per client address within ``login_window_s``; then 429."""
    login_window_s: float = Field(default=60.0, gt=0)
    max_upload_mb: int = Field(default=1024, ge=1)
    demo_camera: bool = True
    """Create a ``demo`` camera at startup when none is configured."""

    # Live cameras.
    jpeg_quality: int = Field(default=80, ge=10, le=100)
    quiet_s: float = Field(default=2.0, gt=0)
    """Seconds without motion that end an event (``motion_end``)."""
    alarm_gap_s: float = Field(default=1.0, ge=0)
    """Shortest time between two alarms of one event; objects joining meanwhile are named
    together by the next alarm."""
    reconnect_min_s: float = Field(default=0.5, gt=0)
    reconnect_max_s: float = Field(default=3.0, gt=0)
    """Longest wait between attempts to reopen a lost camera: it is back within about this
    plus ``open_timeout_ms`` of returning."""
    open_timeout_ms: int = 3000
    read_timeout_ms: int = 2000
    camera_processes: int = Field(default=0, ge=0)
    """Processes the cameras are spread over (0 = one per CPU), each started with its first
    camera: one process's threads are bound by Python's GIL at 20-30 activated 640x480
    cameras on two cores, two processes carry 26-36 (bench/bench_cameras.py)."""
    opencv_threads: int = Field(default=1, ge=0)
    """OpenCV's own worker threads (0 = its default). Each camera has a thread already;
    OpenCV's parallel loops on small frames cost more CPU than they save."""
    worker_failures_limit: int = Field(default=3, ge=1)
    """A camera worker failing this many times in a row shows ``error`` with the reason."""
    bad_frames_limit: int = Field(default=50, ge=1)
    """Undecodable frames in a row after which a camera counts as lost and is reconnected."""
    status_interval_s: float = Field(default=1.0, gt=0)
    """How often each camera reports its state, frame rate and motion on /ws."""
    default_min_area: float = 100.0
    scene_glance_s: float = Field(default=1.0, gt=0)
    """How often a camera keeps a grey frame (idle or detecting): at Activate, the median
    of the last ones is the scene, so what is in view then and moving leaves no ghost."""

    retention_days: float = Field(default=30.0, ge=0)
    """Snapshots, clips, activity and finished events older than this are deleted (0 = keep
    forever)."""
    retention_mb: float = Field(default=2048.0, ge=0)
    """Cap on the snapshots' and clips' total size: the oldest go first, and an ended event
    with its last snapshot and clip (0 = no cap)."""
    retention_interval_s: float = Field(default=60.0, gt=0)
    """How often both limits are applied (and once at start)."""

    # Recordings (app/recording/).
    clips: bool = True
    """Record a clip of each event of an activated camera (H.264 in MP4)."""
    pre_roll_s: float = Field(default=3.0, ge=0, le=60)
    """Seconds of video a clip starts before the event's first moving frame."""
    post_roll_s: float = Field(default=2.0, ge=0, le=60)
    """Seconds of video a clip goes on after the event's last moving frame."""
    pre_roll_mb: float = Field(default=64.0, gt=0)
    """Memory an activated camera's pre-roll may take: frames beyond it are let go, oldest
    first, and the clip starts later (a decoded camera's frames are large: 0.45 MB at
    640x480; a JPEG camera's are its JPEGs). Also what frames waiting for a clip's encoder
    may take: past it, the clip loses frames, never detection."""
    clip_preset: Literal["ultrafast", "superfast", "veryfast", "faster", "fast", "medium"] = (
        "ultrafast"
    )
    """libx264's preset for clips and annotated.mp4 (bench/bench_recording.py)."""
    clip_crf: int = Field(default=26, ge=0, le=51)
    """libx264's constant rate factor: lower is better looking and larger."""

    # Uploads.
    analysis_workers: int = Field(default=1, ge=1)
    """Uploads analysed at the same time (each in its own process)."""
    analysis_timeout_s: float = 3600.0
    max_upload_pixels: int = Field(default=3840 * 2160, ge=1)
    """Largest frame (width x height) an uploaded video may have: 4K UHD. Five megabytes
    of MJPEG can hold 12000x12000 frames that take 9 GB to analyse, so larger is refused."""
    analysis_memory_mb: int = Field(default=8192, ge=0)
    """Address space each analysis process may use (0 = no limit): a decoder that tries
    to allocate more fails that analysis instead of starving the machine."""

    # MQTT and Home Assistant (docs/mqtt.md).
    mqtt_url: str | None = Field(default=None, repr=False)
    """The broker, ``mqtt://user:password@host:1883`` (``mqtts://`` for TLS, port 8883 by
    default); unset or empty: no MQTT at all. Its password is never shown."""
    mqtt_prefix: str = "vigil"
    """The first level of every topic Vigil publishes and listens to."""
    mqtt_discovery_prefix: str = "homeassistant"
    """Home Assistant's discovery prefix; empty: no discovery messages."""
    mqtt_reconnect_max_s: float = Field(default=30.0, ge=0.5)
    """Longest wait between attempts to reach a broker that is down (the wait doubles from
    half a second up to this)."""

    @field_validator("mqtt_url")
    @classmethod
    def _check_mqtt_url(cls, value: str | None) -> str | None:
        if value is None or not value.strip():
            return None
        from app.mqtt.broker import Broker  # Here: app.core imports nothing else of Vigil.

        Broker.parse(value.strip())  # ValueError: the reason, never the password.
        return value.strip()

    @field_validator("database_url")
    @classmethod
    def _check_database_url(cls, value: str | None) -> str | None:
        if value is None or not value.strip():
            return None
        from app.storage.engine import postgres_url  # Here: app.core imports no more of Vigil.

        postgres_url(value)  # ValueError: the reason, never the password.
        return value.strip()

    @field_validator("mqtt_prefix")
    @classmethod
    def _check_mqtt_prefix(cls, value: str) -> str:
        return _topic_prefix(value, "a topic prefix")

    @field_validator("mqtt_discovery_prefix")
    @classmethod
    def _check_discovery_prefix(cls, value: str) -> str:
        return _topic_prefix(value, "a discovery prefix") if value.strip() else ""

    # Several machines (app/nodes, docs/scaling.md): with database_url, the nodes sharing
    # the database (and the MQTT broker) are one site.
    node_name: str = ""
    """This node's name in its site; each node needs its own. Unset: the machine's name."""
    node_url: str = ""
    """How the other nodes and browsers reach this node (``http://10.0.0.5:8000``). Unset:
    ``http://<host>:<port>``."""
    node_cameras: int = Field(default=0, ge=0)
    """Cameras this node runs at most (0: ``CAMERAS_PER_CORE`` per CPU core)."""
    lease_s: float = Field(default=10.0, gt=0)
    """A node that has not renewed its leases for this long is gone: the live nodes take its
    cameras over. It renews three times a lease."""

    @field_validator("node_name")
    @classmethod
    def _check_node_name(cls, value: str) -> str:
        value = value.strip()
        if any(c in value for c in "+#/") or any(not c.isprintable() for c in value):
            raise ValueError("a node's name cannot contain /, +, # or control characters")
        return value

    @field_validator("node_url")
    @classmethod
    def _check_node_url(cls, value: str) -> str:
        return _http_url(value)

    # Notifications (app/notify, docs/notifications.md).
    notify_urls: str = Field(default="", repr=False)
    """Apprise URLs, separated by spaces, each added as a notification target at start
    (``ntfys://my-topic tgram://bot-token/chat-id``). Kept while listed here; deleted when
    no longer listed. Their secrets are shown masked."""
    notify_gap_s: float = Field(default=30.0, ge=0)
    """At most one message per event and target in this many seconds: an event's start
    is always sent; its later alarms only once this long has passed since the last sent."""
    public_url: str = ""
    """The dashboard's address as its users reach it (``https://vigil.example.net``):
    messages then carry links to the dashboard and the snapshot. Empty: no links."""
    notify_timeout_s: float = Field(default=20.0, gt=0)
    """Longest one attempt to send to a target may take (connecting, uploading the
    snapshot, the answer); then it counts as failed."""
    notify_retries: int = Field(default=3, ge=0, le=10)
    """Attempts after the first for a message a target failed to take, waiting
    ``notify_retry_s`` before the first retry and twice as long before each next."""
    notify_retry_s: float = Field(default=2.0, gt=0)
    """The wait before a failed message's first retry (doubled for each next one)."""

    @field_validator("public_url")
    @classmethod
    def _check_public_url(cls, value: str) -> str:
        return _http_url(value)

    @property
    def node(self) -> str:
        """This node's name: ``node_name``, or the machine's."""
        return self.node_name or socket.gethostname()

    @property
    def node_address(self) -> str:
        """How this node is reached: ``node_url``, or ``http://<host>:<port>``."""
        return self.node_url or f"http://{self.host}:{self.port}"

    @property
    def node_capacity(self) -> int:
        """Cameras this node runs at most: ``node_cameras``, or ``CAMERAS_PER_CORE`` per core."""
        return self.node_cameras or CAMERAS_PER_CORE * (os.cpu_count() or 1)

    @property
    def notify_url_list(self) -> list[str]:
        return self.notify_urls.split()

    @property
    def db_path(self) -> Path:
        return self.data_dir / "vigil.db"

    @property
    def database(self) -> Path | str:
        """Where the database is: ``database_url``, or else SQLite's file, ``db_path``."""
        return self.database_url or self.db_path

    @property
    def media(self) -> Path:
        """Where snapshots, clips and analyses go: ``media_dir``, or ``data_dir``."""
        return self.media_dir or self.data_dir

    @property
    def snapshots_dir(self) -> Path:
        return self.media / "snapshots"

    @property
    def clips_dir(self) -> Path:
        return self.media / "clips"

    @property
    def analyses_dir(self) -> Path:
        return self.media / "analyses"


def _http_url(value: str) -> str:
    value = value.strip().rstrip("/")
    if value and not value.lower().startswith(("http://", "https://")):
        raise ValueError("must start with http:// or https://")
    return value


def _topic_prefix(value: str, what: str) -> str:
    """A prefix of MQTT topics: one or more levels, no wildcard, no empty level."""
    value = value.strip()
    if not value:
        raise ValueError(f"{what} cannot be empty")
    if any(c in value for c in "+#\0"):
        raise ValueError(f"{what} cannot contain +, # or a NUL character")
    if "" in value.split("/"):
        raise ValueError(f"{what} cannot start or end with / or contain //")
    return value
