"""Fixtures the MQTT tests share: a topic prefix of their own and a Mosquitto started for the
test (tests/publish/mqtt_harness.Broker). A module that needs another broker (test_sigterm's,
which may leave it stopped) defines its own, which takes precedence."""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.publish.mqtt_harness import Broker


@pytest.fixture
def prefix() -> str:
    return f"t{uuid.uuid4().hex[:8]}"


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Broker]:
    b = Broker(tmp_path)
    b.start()
    yield b
    b.stop()
