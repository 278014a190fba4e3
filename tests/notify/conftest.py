from __future__ import annotations

from collections.abc import Iterator

import pytest

# The live server and Chromium fixtures of the API's tests, used here as they are.
from tests.api.conftest import motion_video, page, serve  # noqa: F401
from tests.notify.receivers import MailReceiver, WebhookReceiver


@pytest.fixture
def webhook() -> Iterator[WebhookReceiver]:
    """A JSON webhook on loopback that takes every message."""
    receiver = WebhookReceiver().start()
    yield receiver
    receiver.stop()


@pytest.fixture
def hanging_webhook() -> Iterator[WebhookReceiver]:
    """A JSON webhook on loopback that takes the request and never answers."""
    receiver = WebhookReceiver(mode="hang").start()
    yield receiver
    receiver.stop()


@pytest.fixture
def mailbox() -> Iterator[MailReceiver]:
    """An SMTP server on loopback (aiosmtpd) that keeps every mail."""
    receiver = MailReceiver().start()
    yield receiver
    receiver.stop()
