"""Under CI a missing Mosquitto fails the broker tests instead of skipping them (issue 42),
as a missing browser, node-opcua or promtool fails theirs: a CI run must never pass with its
MQTT tests silently skipped. TCPCAL_REQUIRE_MOSQUITTO still requires it anywhere."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.publish import mqtt_harness
from tests.publish.mqtt_harness import Broker, skip_without_mosquitto


@pytest.mark.parametrize(
    ("environ", "skipped"),
    [
        ({}, True),  # a workstation without Mosquitto: skipped
        ({"CI": "true"}, False),  # .ci/run, and CI services, set CI
        ({"TCPCAL_REQUIRE_MOSQUITTO": "1"}, False),
        ({"CI": "true", "TCPCAL_REQUIRE_MOSQUITTO": "1"}, False),
    ],
)
def test_a_missing_mosquitto_skips_the_tests_only_where_it_is_not_required(
    environ: dict[str, str], skipped: bool
) -> None:
    assert skip_without_mosquitto(False, environ) is skipped
    assert skip_without_mosquitto(True, environ) is False  # installed: the tests run


def test_where_it_is_required_a_missing_mosquitto_fails_saying_what_to_install(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setattr(mqtt_harness, "MOSQUITTO", str(tmp_path / "no-such-mosquitto"))
    with pytest.raises(pytest.fail.Exception, match="apt-get install mosquitto") as failed:
        Broker(tmp_path)
    assert "CI or TCPCAL_REQUIRE_MOSQUITTO" in str(failed.value)


def test_ci_run_sets_ci() -> None:
    """`.ci/run` exports CI=true (unless the CI service set it already), so that every tool
    the suite needs is required there."""
    script = (Path(__file__).resolve().parents[2] / ".ci" / "run").read_text()
    assert 'export CI="${CI:-true}"' in script
