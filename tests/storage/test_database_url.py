"""``VIGIL_DATABASE_URL``: which database, checked at start, and its password never shown."""

from __future__ import annotations

from pathlib import Path

import pytest
from pydantic import ValidationError

from app.core.config import Settings
from app.storage.engine import postgres_url, shown


def test_without_it_the_database_is_sqlite_in_the_data_folder(tmp_path: Path) -> None:
    for unset in (None, "", "  "):
        settings = Settings(data_dir=tmp_path, database_url=unset)
        assert settings.database_url is None and settings.database == tmp_path / "vigil.db"


def test_a_postgresql_url_is_the_database_and_its_password_is_never_shown() -> None:
    url = "postgresql://vigil:hunter2@db.example:5433/site?sslmode=require"
    settings = Settings(database_url=f" {url} ")
    assert settings.database == url
    assert "hunter2" not in repr(settings) and "hunter2" not in str(settings)
    assert shown(url) == "postgresql://vigil:***@db.example:5433/site?sslmode=require"
    assert shown("postgres://vigil@db/site?password=hunter2&sslmode=require") == (
        "postgresql://vigil@db/site?sslmode=require"
    )
    assert shown(Path("data/vigil.db")) == "data/vigil.db"
    assert postgres_url("postgres://u:p%40ss@h/d").password == "p@ss"
    assert postgres_url(url).drivername == "postgresql+psycopg"


@pytest.mark.parametrize(
    ("url", "reason"),
    [
        ("mysql://u:hunter2@host/db", "mysql:// is not PostgreSQL"),
        ("postgresql://u:hunter2@host", "names no database"),
        ("postgresql://u:hunter2@host:port/db", "not a database URL"),
        ("u:hunter2@host/db", "not a database URL"),
    ],
)
def test_a_url_that_is_not_postgresql_stops_the_start_without_its_password(
    url: str, reason: str
) -> None:
    with pytest.raises(ValidationError) as refused:
        Settings(database_url=url)
    (error,) = refused.value.errors()
    assert error["loc"] == ("database_url",) and reason in error["msg"]
    assert "hunter2" not in error["msg"]
