"""compose.yaml's broker and publisher: wired to each other, and the broker's configuration
accepted by a real Mosquitto (its paths pointed at a temporary directory)."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
import yaml

from app.publish.mqtt import parse_url
from tests.polling import wait_for
from tests.publish.mqtt_harness import (
    MOSQUITTO,
    MOSQUITTO_PASSWD,
    free_port,
    needs_mosquitto,
    require_mosquitto,
)

REPO = Path(__file__).resolve().parents[2]
CONF = REPO / "deploy" / "mosquitto" / "mosquitto.conf"


def test_compose_runs_a_broker_and_one_publisher_wired_to_it() -> None:
    services = yaml.safe_load((REPO / "compose.yaml").read_text())["services"]
    publisher, mqtt = services["publisher"], services["mqtt"]
    assert publisher["command"] == ["tcpcal", "publish"]
    env = publisher["environment"]
    url = env["TCPCAL_MQTT_URL"].replace("${TCPCAL_MQTT_USER:-tcpcal}", "tcpcal")
    url = url.replace("${TCPCAL_MQTT_PASSWORD:-tcpcal}", "pw")
    broker = parse_url(url)
    assert (broker.host, broker.port, broker.username) == ("mqtt", 1883, "tcpcal")
    assert env["TCPCAL_DATABASE_URL"] == services["tcpcal"]["environment"]["TCPCAL_DATABASE_URL"]
    assert publisher["depends_on"]["tcpcal"]["condition"] == "service_healthy"  # migrated
    assert publisher["restart"] == "unless-stopped"
    assert "replicas" not in publisher.get("deploy", {})  # one per fleet
    assert "1883:1883" in mqtt["ports"]
    assert any("mosquitto.conf" in v for v in mqtt["volumes"])


@pytest.mark.live
@needs_mosquitto
def test_the_broker_configuration_loads_and_refuses_anonymous_clients(tmp_path: Path) -> None:
    require_mosquitto()
    port = free_port()
    conf = CONF.read_text().replace("/mosquitto/data/", f"{tmp_path}/")
    conf = conf.replace("listener 1883", f"listener {port} 127.0.0.1") + "user root\n"
    (tmp_path / "mosquitto.conf").write_text(conf)
    subprocess.run(
        [MOSQUITTO_PASSWD, "-b", "-c", str(tmp_path / "passwd"), "tcpcal", "pw"], check=True
    )
    broker = subprocess.Popen(
        [MOSQUITTO, "-c", str(tmp_path / "mosquitto.conf")],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    try:
        anonymous = ["mosquitto_pub", "-p", str(port), "-t", "x", "-m", "1", "-q", "1"]
        signed_in = [*anonymous, "-u", "tcpcal", "-P", "pw"]

        def accepts_sign_in() -> bool:
            return subprocess.run(signed_in, capture_output=True, timeout=10).returncode == 0

        wait_for(accepts_sign_in, 10, "the broker accepting the configured user")
        refused = subprocess.run(anonymous, capture_output=True, timeout=10)
        assert refused.returncode != 0
    finally:
        broker.terminate()
        broker.wait(10)
