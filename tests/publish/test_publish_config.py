"""A publisher that cannot publish says why at start-up and exits non-zero; the API does not
need it (changes wait in the outbox, and /metrics shows how long)."""

from __future__ import annotations

import os
import re
import time
from pathlib import Path

import pytest

from app.publish.mqtt import check_prefix, parse_url
from app.publish.sink import SinkError
from tests.conftest import Api, one_backend
from tests.polling import wait_for
from tests.publish.mqtt_harness import (
    Broker,
    Publisher,
    Subscriber,
    free_port,
    needs_mosquitto,
    run_publisher_once,
)


@pytest.mark.parametrize(
    ("url", "says"),
    [
        ("http://127.0.0.1:1883", "scheme 'http' is not mqtt or mqtts"),
        ("mqtt://127.0.0.1:99999", "malformed"),
        ("mqtt://127.0.0.1:port", "malformed"),
        ("mqtt://:1883", "names no host"),
        ("127.0.0.1:1883", "is not mqtt or mqtts"),
        ("mqtt://127.0.0.1:1883/topic", "path or query"),
    ],
)
def test_malformed_urls_are_refused_with_the_reason(url: str, says: str) -> None:
    with pytest.raises(SinkError, match=re.escape(says)) as refused:
        parse_url(url)
    assert "mqtt://user:pass@host:1883" in str(refused.value)  # and what to write instead


def test_urls_are_taken_apart() -> None:
    plain = parse_url("mqtt://127.0.0.1")
    assert (plain.host, plain.port, plain.tls, plain.username) == ("127.0.0.1", 1883, False, None)
    tls = parse_url("mqtts://plant%40site:p%3Ass@broker.example:8884")
    assert (tls.host, tls.port, tls.tls) == ("broker.example", 8884, True)
    assert (tls.username, tls.password) == ("plant@site", "p:ss")
    assert "p:ss" not in tls.where


@pytest.mark.parametrize("prefix", ["", "/tcpcal", "tcpcal/", "plant/+", "a#"])
def test_bad_prefixes_are_refused(prefix: str) -> None:
    with pytest.raises(SinkError, match="TCPCAL_MQTT_PREFIX"):
        check_prefix(prefix)


@pytest.mark.live
@one_backend
def test_unreachable_broker_and_malformed_url_exit_non_zero(api: Api) -> None:
    database_url = os.environ["TCPCAL_DATABASE_URL"]
    port = free_port()  # nothing listens there
    code, output = run_publisher_once(database_url, f"mqtt://127.0.0.1:{port}")
    assert code == 2, output
    assert f"cannot reach the MQTT broker at mqtt://127.0.0.1:{port}" in output
    code, output = run_publisher_once(database_url, "mqtt//127.0.0.1:1883")
    assert code == 2, output
    assert "TCPCAL_MQTT_URL" in output


@pytest.mark.live
@needs_mosquitto
@one_backend
def test_wrong_password_exits_non_zero_and_the_right_one_publishes(
    api: Api, tmp_path: Path
) -> None:
    broker = Broker(tmp_path, users={"plant": "s3cret"})
    broker.start()
    try:
        database_url = os.environ["TCPCAL_DATABASE_URL"]
        code, output = run_publisher_once(database_url, broker.url("plant", "wrong"))
        assert code == 2, output
        assert "refused the connection" in output
        assert "user name and password" in output
        assert "wrong" not in output  # the password is never printed
        right = Publisher(tmp_path, database_url, broker.url("plant", "s3cret"), "auth").start()
        try:
            wait_for(lambda: "publishing to mqtt" in right.output(), 60, "the publisher running")
        finally:
            assert right.terminate() < 1.0
    finally:
        broker.stop()


@pytest.mark.live
@one_backend
def test_no_broker_configured_exits_non_zero(api: Api) -> None:
    code, output = run_publisher_once(os.environ["TCPCAL_DATABASE_URL"], "")
    assert code == 2, output
    assert "nothing to publish to: set TCPCAL_MQTT_URL" in output


def test_the_api_serves_without_a_publisher_and_metrics_show_the_backlog(api: Api) -> None:
    robot = api.robot("r-alone")
    tool = api.tool(robot["id"], "t")
    api.manual(tool["id"], [1.0, 2.0, 3.0])
    assert api.get(f"/v1/tools/{tool['id']}/tcp").status_code == 200
    time.sleep(1.1)
    metrics = api.get("/metrics").text
    found = re.search(r"^tcpcal_outbox_oldest_undelivered_age_seconds (\S+)$", metrics, re.M)
    assert found is not None, metrics[-2000:]
    assert float(found.group(1)) >= 1.0
    waiting = re.search(r"^tcpcal_outbox_undelivered (\S+)$", metrics, re.M)
    assert waiting is not None
    assert float(waiting.group(1)) >= 3  # robot, tool, calibration (and its version)


@pytest.mark.live
@needs_mosquitto
@one_backend
def test_tls_with_the_ca_publishes_and_without_it_exits_non_zero(api: Api, tmp_path: Path) -> None:
    broker = Broker(tmp_path, tls=True)
    broker.start()
    try:
        database_url = os.environ["TCPCAL_DATABASE_URL"]
        assert broker.url().startswith("mqtts://")
        code, output = run_publisher_once(database_url, broker.url())  # the system's CAs
        assert code == 2, output
        assert "certificate verify failed" in output
        sub = Subscriber(broker, "tls")
        publisher = Publisher(
            tmp_path, database_url, broker.url(), "tls", TCPCAL_MQTT_CA_FILE=str(broker.ca_file)
        ).start()
        try:
            wait_for(
                lambda: [m.payload for m in sub.on("status")][-1:] == [b"online"],
                60,
                "the publisher online over TLS",
            )
        finally:
            assert publisher.terminate() < 1.0
            sub.close()
    finally:
        broker.stop()
