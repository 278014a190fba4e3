"""VIGIL_MQTT_URL and the other MQTT settings: parsed, checked, never showing the password."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from pydantic import ValidationError

from app.core.config import Settings
from app.mqtt.broker import Broker
from tests.api.vigil_livekit import ROOT


def test_broker_url() -> None:
    plain = Broker.parse("mqtt://vigil:s%40cret@broker.lan")
    assert (plain.host, plain.port, plain.tls) == ("broker.lan", 1883, False)
    assert (plain.username, plain.password) == ("vigil", "s@cret")
    assert str(plain) == "mqtt://vigil@broker.lan:1883" and "s@cret" not in repr(plain)
    tls = Broker.parse("MQTTS://[::1]")
    assert (tls.host, tls.port, tls.tls, tls.username) == ("::1", 8883, True, None)
    assert str(tls) == "mqtts://[::1]:8883"
    assert Broker.parse("mqtt://10.0.0.2:1999").port == 1999
    for bad, reason in [
        ("http://broker", "mqtt:// or mqtts://"),
        ("broker:1883", "mqtt:// or mqtts://"),
        ("mqtt://", "no host"),
        ("mqtt://u:p@host:99999", "not a broker URL"),
        ("mqtt://host:0", "port 0"),
        ("mqtt://host/topic", "no path or query"),
    ]:
        with pytest.raises(ValueError, match=reason):
            Broker.parse(bad)


def test_settings() -> None:
    default = Settings(_env_file=None)
    assert default.mqtt_url is None
    assert (default.mqtt_prefix, default.mqtt_discovery_prefix) == ("vigil", "homeassistant")
    assert Settings(mqtt_url="  ").mqtt_url is None
    assert Settings(mqtt_discovery_prefix="").mqtt_discovery_prefix == ""
    assert Settings(mqtt_prefix="home/vigil").mqtt_prefix == "home/vigil"
    secret = Settings(mqtt_url="mqtt://u:hunter2@host")
    assert "hunter2" not in repr(secret)
    for field, value in [
        ("mqtt_url", "ftp://host"),
        ("mqtt_prefix", ""),
        ("mqtt_prefix", "vigil/#"),
        ("mqtt_prefix", "a/+/b"),
        ("mqtt_prefix", "/vigil"),
        ("mqtt_prefix", "vigil/"),
        ("mqtt_discovery_prefix", "ha//x"),
        ("mqtt_reconnect_max_s", 0.1),
    ]:
        with pytest.raises(ValidationError):
            Settings(**{field: value})


def test_serve_refuses_a_bad_broker_url_in_one_line_without_its_password(tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "VIGIL_MQTT_URL": "htp://me:hunter2@host"}
    done = subprocess.run(
        [sys.executable, "-m", "app", "serve", "--data", str(tmp_path)],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode != 0
    assert "VIGIL_MQTT_URL" in done.stderr and "mqtt:// or mqtts://" in done.stderr
    assert "hunter2" not in done.stderr + done.stdout
    assert len(done.stderr.strip().splitlines()) == 1
