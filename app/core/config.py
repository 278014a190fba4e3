"""Settings in one place: defaults, overridden by ``VIGIL_*`` environment variables."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

MAX_PORT = 65535


class Settings(BaseSettings):
    """What ``vigil serve`` runs with (``VIGIL_PORT=9000``, ``VIGIL_DATA_DIR=/srv/vigil``...)."""

    model_config = SettingsConfigDict(env_prefix="VIGIL_", extra="ignore")

    host: str = "127.0.0.1"
    port: int = Field(default=8000, ge=1, le=MAX_PORT)
    data_dir: Path = Path("data")
    """Holds vigil.db (SQLite), snapshots/, clips/ and analyses/."""
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

    @property
    def db_path(self) -> Path:
        return self.data_dir / "vigil.db"

    @property
    def snapshots_dir(self) -> Path:
        return self.data_dir / "snapshots"

    @property
    def clips_dir(self) -> Path:
        return self.data_dir / "clips"

    @property
    def analyses_dir(self) -> Path:
        return self.data_dir / "analyses"
