"""`tcpcal connect`, `tcpcal connection` and `tcpcal disconnect` against the in-process app:
what the server answers in words (protocol, host, the ports in use, scope), a 422 naming the
option to change, and a password that never reaches the output."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from app.cli import cli
from app.cli.controllers import LIVE_SCOPE
from tests.api.controller_rigs import secret_key as secret_key  # the passwords' key, autouse
from tests.cli.in_process import cli_as
from tests.conftest import Api

PASSWORD = "tm5-s3cret-pw"


@pytest.fixture
def runner(api: Api, monkeypatch: pytest.MonkeyPatch) -> CliRunner:
    """The commands talk to the in-process app with an admin key (connections are admin's)."""

    return cli_as("admin", api, monkeypatch)


def test_a_techman_connection_with_ports_by_robot_name(api: Api, runner: CliRunner) -> None:
    robot = api.robot("cell7-tm5")
    done = runner.invoke(
        cli,
        ["connect", "cell7-tm5", "--protocol", "techman", "--host", "127.0.0.1",
         "--ports", "listen_node=15890", "--ports", "ethernet_slave=15891", "--timeout", "2"],
    )  # fmt: skip
    assert done.exit_code == 0, done.output
    assert "robot cell7-tm5: techman at 127.0.0.1 (listen_node 15890, ethernet_slave 15891)\n" in (
        done.output
    )
    assert "  scope     live\n" in done.output
    assert "  timeout   2 s\n" in done.output
    assert LIVE_SCOPE in done.output
    stored = api.get(f"/v1/robots/{robot['id']}/controller").json()
    assert stored["ports"] == {"listen_node": 15890, "ethernet_slave": 15891}
    # a service left out keeps its default
    one = runner.invoke(
        cli,
        ["connect", robot["id"], "--protocol", "techman", "--host", "127.0.0.1",
         "--ports", "ethernet_slave=15891"],
    )  # fmt: skip
    assert one.exit_code == 0, one.output
    assert "(listen_node 5890, ethernet_slave 15891)" in one.output
    shown = runner.invoke(cli, ["connection", "cell7-tm5"])
    assert shown.exit_code == 0, shown.output
    assert "techman at 127.0.0.1 (listen_node 5890, ethernet_slave 15891)" in shown.output
    gone = runner.invoke(cli, ["disconnect", "cell7-tm5"])
    assert gone.exit_code == 0, gone.output
    assert "robot cell7-tm5: no controller connection" in gone.output
    none = runner.invoke(cli, ["connection", "cell7-tm5"])
    assert none.exit_code == 5, none.output
    assert api.get(f"/v1/robots/{robot['id']}/controller").status_code == 404


def test_a_single_port_protocol_with_port(api: Api, runner: CliRunner) -> None:
    api.robot("cell12-kr16")
    done = runner.invoke(
        cli, ["connect", "cell12-kr16", "--protocol", "kuka_kvp", "--host", "127.0.0.1",
              "--port", "17000"],
    )  # fmt: skip
    assert done.exit_code == 0, done.output
    assert "robot cell12-kr16: kuka_kvp at 127.0.0.1:17000\n" in done.output
    assert "  scope     stored\n" in done.output
    assert "live:" not in done.output


def test_a_wrong_shape_is_refused_in_words_naming_the_option(api: Api, runner: CliRunner) -> None:
    robot = api.robot("cell3-ur10e")
    several = runner.invoke(
        cli, ["connect", "cell3-ur10e", "--protocol", "ur_rtde", "--host", "127.0.0.1",
              "--port", "30004"],
    )  # fmt: skip
    assert several.exit_code == 4, several.output
    assert "422: --port: ur_rtde is reached on several ports" in several.output
    assert "give them as `ports`" in several.output
    unknown = runner.invoke(
        cli, ["connect", "cell3-ur10e", "--protocol", "ur_rtde", "--host", "127.0.0.1",
              "--ports", "dashboard=29999"],
    )  # fmt: skip
    assert unknown.exit_code == 4, unknown.output
    assert "422: --ports:" in unknown.output
    assert "ur_rtde has no service 'dashboard'" in unknown.output
    malformed = runner.invoke(
        cli, ["connect", "cell3-ur10e", "--protocol", "ur_rtde", "--host", "127.0.0.1",
              "--ports", "rtde:30004"],
    )  # fmt: skip
    assert malformed.exit_code == 2, malformed.output
    assert "--ports takes SERVICE=PORT" in malformed.output
    assert api.get(f"/v1/robots/{robot['id']}/controller").status_code == 404


@pytest.mark.parametrize("how", ["--password-stdin", "--password-prompt"])
def test_the_password_is_stored_and_never_shown(api: Api, runner: CliRunner, how: str) -> None:
    robot = api.robot("cell9-irb")
    done = runner.invoke(
        cli,
        ["connect", "cell9-irb", "--protocol", "abb_rws2", "--host", "127.0.0.1",
         "--user", "Default User", how],
        input=f"{PASSWORD}\n",
    )  # fmt: skip
    assert done.exit_code == 0, done.output
    assert PASSWORD not in done.output
    assert "  password    stored\n" in done.output
    assert "  user        Default User\n" in done.output
    stored = api.get(f"/v1/robots/{robot['id']}/controller").json()
    assert stored["has_password"] is True
    # a new connection without a password option keeps the stored one
    kept = runner.invoke(
        cli, ["connect", "cell9-irb", "--protocol", "abb_rws2", "--host", "127.0.0.1"]
    )
    assert kept.exit_code == 0, kept.output
    assert "  password    stored\n" in kept.output


def test_forget_password_removes_the_stored_one(api: Api, runner: CliRunner) -> None:
    """Issue 51: a stored password could not be removed from the CLI (a controller whose
    user needs none any more kept sending it)."""
    robot = api.robot("cell9-irb")
    connect = ["connect", "cell9-irb", "--protocol", "abb_rws2", "--host", "127.0.0.1"]
    stored = runner.invoke(cli, [*connect, "--password-stdin"], input=f"{PASSWORD}\n")
    assert stored.exit_code == 0, stored.output
    assert api.get(f"/v1/robots/{robot['id']}/controller").json()["has_password"] is True
    both = runner.invoke(cli, [*connect, "--password-stdin", "--forget-password"], input="x\n")
    assert both.exit_code == 2, both.output
    assert "--forget-password removes the stored password" in " ".join(both.output.split())
    assert api.get(f"/v1/robots/{robot['id']}/controller").json()["has_password"] is True
    forgot = runner.invoke(cli, [*connect, "--forget-password"])
    assert forgot.exit_code == 0, forgot.output
    assert "  password    none\n" in forgot.output
    assert api.get(f"/v1/robots/{robot['id']}/controller").json()["has_password"] is False


def test_a_protocol_of_another_maker_is_refused_naming_the_option(
    api: Api, runner: CliRunner
) -> None:
    robot = api.robot("cell2-kr16", vendor="KUKA")
    refused = runner.invoke(
        cli, ["connect", "cell2-kr16", "--protocol", "techman", "--host", "127.0.0.1"]
    )
    assert refused.exit_code == 4, refused.output
    said = " ".join(refused.output.split())
    assert "422: --protocol: protocol techman is not its robot's" in said, said
    assert "its controllers speak kuka_kvp" in said
    assert api.get(f"/v1/robots/{robot['id']}/controller").status_code == 404
    patch = f"PATCH /v1/robots/{robot['id']}"
    assert f"if the vendor is wrong, correct the robot's vendor ({patch})" in said


def test_a_wrong_vendor_with_a_controller_is_advised_to_disconnect_first(
    api: Api, runner: CliRunner
) -> None:
    """The vendor's PATCH is refused while the robot has a controller another maker's
    controllers do not speak: the advice for a wrong vendor names the disconnect first, and
    followed step by step it connects."""
    robot = api.robot("cell3-kr16", vendor="KUKA")
    first = ["connect", "cell3-kr16", "--protocol", "kuka_kvp", "--host", "127.0.0.1"]
    assert runner.invoke(cli, first).exit_code == 0
    techman = ["connect", "cell3-kr16", "--protocol", "techman", "--host", "127.0.0.1"]
    refused = runner.invoke(cli, techman)
    assert refused.exit_code == 4, refused.output
    said = " ".join(refused.output.split())
    assert (
        "remove its controller first (DELETE /v1/robots/"
        f"{robot['id']}/controller, or tcpcal disconnect cell3-kr16), then correct the robot's "
        f"vendor (PATCH /v1/robots/{robot['id']}) and connect it again"
    ) in said, said
    patched_first = api.patch(f"/v1/robots/{robot['id']}", json={"vendor": "Techman"})
    assert patched_first.status_code == 422  # what the advice steers around
    assert runner.invoke(cli, ["disconnect", "cell3-kr16"]).exit_code == 0
    assert api.patch(f"/v1/robots/{robot['id']}", json={"vendor": "Techman"}).status_code == 200
    assert runner.invoke(cli, techman).exit_code == 0


def test_changing_a_connection_needs_admin(
    api: Api, runner: CliRunner, monkeypatch: pytest.MonkeyPatch
) -> None:
    api.robot("cell1-kr6")

    runner = cli_as("calibrate", api, monkeypatch)
    refused = runner.invoke(
        cli, ["connect", "cell1-kr6", "--protocol", "kuka_kvp", "--host", "127.0.0.1"]
    )
    assert refused.exit_code == 5, refused.output
    assert "403" in refused.output


def test_help_names_every_protocol_and_service() -> None:
    from app.vendors.registry import SERVICE_PORTS
    from app.words import PROTOCOLS

    shown = CliRunner().invoke(cli, ["connect", "--help"], env={"COLUMNS": "400"}).output
    for protocol in PROTOCOLS:
        assert protocol in shown
    for multi, services in SERVICE_PORTS.items():
        assert f"{multi} {', '.join(services)}" in shown
    assert "--no-password-stdin" not in shown
