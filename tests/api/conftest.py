from __future__ import annotations

import shutil
from collections.abc import Callable, Iterator
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import pytest

from tests.api.vigil_livekit import Running, live_settings, running_server, write_video
from tests.mqtt.mosquitto import Mosquitto


@pytest.fixture
def motion_video(tmp_path: Path) -> Path:
    return write_video(tmp_path / "motion.avi")


@pytest.fixture
def serve(tmp_path: Path) -> Iterator[Callable[..., Running]]:
    """Start a real uvicorn with a data folder in tmp_path; stopped at the end of the test."""
    with ExitStack() as stack:

        def start(data_dir: Path | None = None, **overrides: Any) -> Running:
            settings = live_settings(data_dir or tmp_path / "data", **overrides)
            return stack.enter_context(running_server(settings))

        yield start


@pytest.fixture
def mosquitto(tmp_path: Path) -> Iterator[Callable[..., Mosquitto]]:
    """Start a real Mosquitto on a free loopback port (skips where it is not installed);
    every broker started is stopped at the end of the test."""
    brokers: list[Mosquitto] = []

    def start(**options: Any) -> Mosquitto:
        broker = Mosquitto(tmp_path / f"broker{len(brokers)}", **options)
        brokers.append(broker)
        return broker.start()

    try:
        yield start
    finally:
        for broker in brokers:
            broker.stop()


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMIUM_FLAGS = [  # Quiet on a closed network (NOTES.md).
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


@pytest.fixture
def page() -> Iterator[Any]:
    """A Chromium page that records every Content-Security-Policy violation in window.__csp."""
    sync_api = pytest.importorskip("playwright.sync_api")
    if CHROMIUM is None:
        pytest.skip("Chromium is not installed")
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_FLAGS)
        try:
            context = browser.new_context(viewport={"width": 1400, "height": 1000})
            context.add_init_script(
                "window.__csp = [];"
                "document.addEventListener('securitypolicyviolation', e =>"
                " window.__csp.push(e.violatedDirective + ' ' + e.blockedURI));"
            )
            yield context.new_page()
        finally:
            browser.close()
