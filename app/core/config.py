"""Settings in one place: defaults, overridden by ``VIGIL_*`` environment variables."""

from __future__ import annotations

from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict


class Settings(BaseSettings):
    """What ``vigil serve`` runs with (``VIGIL_PORT=9000``, ``VIGIL_DATA_DIR=/srv/vigil``...)."""

    model_config = SettingsConfigDict(env_prefix="VIGIL_", extra="ignore")

    host: str = "127.0.0.1"
    port: int = 8000
    data_dir: Path = Path("data")
    """Holds vigil.db (SQLite), snapshots/ and analyses/."""
    password: str | None = None
    """When set, every page and API call needs HTTP basic auth with this password."""
    max_upload_mb: int = Field(default=1024, ge=1)
    demo_camera: bool = True
    """Create a ``demo`` camera at startup when none is configured."""

    # Live cameras.
    jpeg_quality: int = Field(default=80, ge=10, le=100)
    quiet_s: float = Field(default=2.0, gt=0)
    """Seconds without motion that end an event (``motion_end``)."""
    reconnect_min_s: float = Field(default=0.5, gt=0)
    reconnect_max_s: float = Field(default=15.0, gt=0)
    open_timeout_ms: int = 3000
    read_timeout_ms: int = 2000
    status_interval_s: float = Field(default=1.0, gt=0)
    """How often each camera reports its state, frame rate and motion on /ws."""
    default_min_area: float = 100.0

    retention_days: float = Field(default=30.0, ge=0)
    """Snapshots and finished events older than this are deleted (0 = keep forever)."""

    # Uploads.
    analysis_workers: int = Field(default=1, ge=1)
    """Uploads analysed at the same time (each in its own process)."""
    analysis_timeout_s: float = 3600.0

    @property
    def db_path(self) -> Path:
        return self.data_dir / "vigil.db"

    @property
    def snapshots_dir(self) -> Path:
        return self.data_dir / "snapshots"

    @property
    def analyses_dir(self) -> Path:
        return self.data_dir / "analyses"
