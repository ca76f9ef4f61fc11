"""The cell PC's client (`tcpcal tools|calibrate|history|activate|rollback|check|export`)
against a live server, through typer's runner: tables, the verdict sentence, exit codes."""

from __future__ import annotations

import csv
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from app.cli import cli
from app.kinematics.poses import pose_to_format
from app.vendors.registry import parse_controller_file
from testbed.live_server import LiveServer, fresh_database, live_server
from testbed.sim.touches import Touches, simulate_touches

pytestmark = pytest.mark.live


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LiveServer]:
    tmp = tmp_path_factory.mktemp("client")
    with fresh_database("sqlite", tmp, None) as url, live_server(url, workers=1, solvers=0) as srv:
        yield srv


@pytest.fixture
def run(server: LiveServer, monkeypatch: pytest.MonkeyPatch) -> CliRunner:
    monkeypatch.setenv("TCPCAL_URL", server.url)
    monkeypatch.setenv("TCPCAL_API_KEY", server.admin_key)
    monkeypatch.setenv("COLUMNS", "200")
    return CliRunner()


def _write_csv(path: Path, touches: Touches, fmt: str, units: dict[str, str] | None = None) -> Path:
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["X", "Y", "Z", "A", "B", "C"])  # a pendant export's header line
        for R, f in zip(touches.R, touches.f, strict=True):
            writer.writerow(pose_to_format(fmt, R, f, units=units))
    return path


def test_client_calibrates_lists_rolls_back_exports_and_checks(
    server: LiveServer, run: CliRunner, tmp_path: Path
) -> None:
    with server.client() as http:
        robot = http.post("/v1/robots", json={"name": "kr16", "cell": "weld-3"}).json()
        tool = http.post(
            f"/v1/robots/{robot['id']}/tools", json={"name": "torch", "slot": 3}
        ).json()
    tid = tool["id"]
    touches = simulate_touches(8, seed=11, touch_noise_mm=0.05)

    good = _write_csv(tmp_path / "good.csv", touches, "kuka_abc")
    result = run.invoke(
        cli, ["calibrate", tid, str(good), "--format", "kuka_abc", "--note", "new torch"]
    )
    assert result.exit_code == 0, result.output
    assert "accepted: TCP (" in result.output
    with server.client() as http:
        stored = http.get(f"/v1/tools/{tid}/calibrations").json()["items"][0]
    z = stored["tcp"]["position_mm"][2]
    assert f"{z:.3f}" in result.output  # the table shows mm to 3 decimals
    assert abs(z - touches.t[2]) < 0.5

    # the same touches written in metres: refused with the suggestion, exit 4, nothing stored
    metres = _write_csv(tmp_path / "m.csv", touches, "kuka_abc", {"length": "m"})
    refused = run.invoke(cli, ["calibrate", tid, str(metres), "--format", "kuka_abc"])
    assert refused.exit_code == 4, refused.output
    assert '"length": "m"' in refused.output
    accepted_in_m = run.invoke(
        cli, ["calibrate", tid, str(metres), "--format", "kuka_abc", "--length", "m"]
    )
    assert accepted_in_m.exit_code == 0, accepted_in_m.output

    noisy = _write_csv(
        tmp_path / "noisy.csv", simulate_touches(8, seed=3, touch_noise_mm=1.5), "kuka_abc"
    )
    out_of_tol = run.invoke(cli, ["calibrate", tid, str(noisy), "--format", "kuka_abc"])
    assert out_of_tol.exit_code == 3, out_of_tol.output
    assert "out of tolerance" in out_of_tol.output

    bad = tmp_path / "bad.csv"
    bad.write_text("1,2,3,4,5\n1,2,3,4,5\n1,2,3,4,5\n1,2,3,4,5\n")
    local = run.invoke(cli, ["calibrate", tid, str(bad), "--format", "kuka_abc"])
    assert local.exit_code == 2
    assert "expected 6 numbers" in local.output

    fleet = run.invoke(cli, ["tools", "--cell", "weld-3"])
    assert fleet.exit_code == 0, fleet.output
    assert "torch" in fleet.output
    assert "out_of_tolerance" in fleet.output
    exported_csv = tmp_path / "fleet.csv"
    assert run.invoke(cli, ["tools", "--csv", str(exported_csv)]).exit_code == 0
    assert len(list(csv.DictReader(exported_csv.open()))) == 1

    history = run.invoke(cli, ["history", tid])
    assert history.exit_code == 0
    assert "new torch" in history.output
    rolled = run.invoke(cli, ["rollback", tid])
    assert rolled.exit_code == 0, rolled.output
    assert "version 1 is active" in rolled.output
    assert run.invoke(cli, ["rollback", tid]).exit_code == 4  # nothing before version 1
    assert run.invoke(cli, ["activate", tid, "2"]).exit_code == 0

    exported = run.invoke(cli, ["export", tid, "--format", "kuka", "-o", str(tmp_path)])
    assert exported.exit_code == 0, exported.output
    text = (tmp_path / "tool3_torch.dat").read_text()
    assert text.startswith("; tcpcal tool data\n")  # the $config.dat lines, with their header
    assert "\nTOOL_DATA[3]={X " in text

    # A fleet backup: every robot's files, each in the formats of its vendor (all six when the
    # vendor is not known), and the tool table as JSON; each file reads back to the active TCP.
    with server.client() as http:
        abb = http.post("/v1/robots", json={"name": "irb 🤖 4600", "vendor": "ABB"}).json()
        gun = http.post(
            f"/v1/robots/{abb['id']}/tools",
            json={"name": "tGun", "load": {"mass_kg": 3.2, "cog_mm": [0, 0, 90]}},
        ).json()
        http.post(
            f"/v1/tools/{gun['id']}/calibrations",
            json={"method": "manual", "tcp": {"position_mm": [0, 0, 250]}},
        ).raise_for_status()
        active = http.get(f"/v1/tools/{tid}/tcp").json()["tcp"]["position_mm"]
    backup = tmp_path / "backup"
    written = run.invoke(cli, ["export", "--all", str(backup)])
    assert written.exit_code == 0, written.output
    assert sorted(p.name for p in (backup / "irb_4600").iterdir()) == [
        "tcpcal_tools.mod",
        "tool-table.json",
    ]
    kuka_files = sorted(p.name for p in (backup / "kr16").iterdir())
    assert kuka_files == [
        "TCPUTALL.LS", "TOOL.CND", "TOOL.CND.README.txt", "config_tools.dat",
        "tcpcal_tools.mod", "tcpcal_tools.script", "tcpcal_tools.txt", "tool-table.json",
    ]  # fmt: skip
    # TOOL.CND has no comments: what it changes is said beside it
    assert "may clear the other tools" in (backup / "kr16" / "TOOL.CND.README.txt").read_text()
    for fmt, name in [("fanuc", "TCPUTALL.LS"), ("kuka", "config_tools.dat")]:
        (parsed,) = [
            t
            for t in parse_controller_file(fmt, (backup / "kr16" / name).read_text())
            if t.slot == 3
        ]
        assert np.allclose(parsed.position_mm, active, atol=1e-3)
    (rapid,) = parse_controller_file("abb", (backup / "irb_4600" / "tcpcal_tools.mod").read_text())
    assert (rapid.name, rapid.mass_kg) == ("tGun", 3.2)
    assert "left out: torch" in (backup / "kr16" / "tcpcal_tools.mod").read_text()
    bad_use = run.invoke(cli, ["export", tid, "--all", str(backup)])
    assert bad_use.exit_code == 2

    # Yaskawa: the tool's block merged into the controller's own TOOL.CND (a DX100 backup's
    # first five tools), every other block kept byte for byte
    saved = Path(__file__).parents[1] / "data" / "controller-files" / "yaskawa_TOOL.CND"
    merged_path = tmp_path / "merged.CND"
    args = [
        "export",
        tid,
        "--format",
        "yaskawa",
        "--merge-into",
        str(saved),
        "-o",
        str(merged_path),
    ]
    merged = run.invoke(cli, args)
    assert merged.exit_code == 0, merged.output
    merged_text, saved_text = merged_path.read_text(), saved.read_text()
    assert merged_text.startswith(saved_text.split("//TOOL 3\n")[0])
    assert merged_text.endswith(saved_text[saved_text.index("//TOOL 4\n") :])
    blocks = {t.slot: t for t in parse_controller_file("yaskawa", merged_text)}
    assert list(blocks) == [0, 1, 2, 3, 4]
    assert np.allclose(blocks[3].position_mm, active, atol=1e-3)
    assert run.invoke(cli, [*args[:3], "kuka", *args[4:]]).exit_code == 2  # yaskawa only

    with server.client() as http:
        pin = http.post(
            f"/v1/robots/{robot['id']}/reference-points",
            json={"name": "pin", "position_mm": [float(v) for v in touches.p]},
        ).json()
    one = simulate_touches(2, seed=11, touch_noise_mm=0.0, tcp_mm=touches.t, pivot_mm=touches.p)
    checked = run.invoke(
        cli, ["check", tid, pin["id"], str(_write_csv(tmp_path / "c.csv", one, "kuka_abc")),
              "--format", "kuka_abc"],
    )  # fmt: skip
    assert checked.exit_code == 0, checked.output
    assert "within tolerance" in checked.output

    assert run.invoke(cli, ["history", "no-such-tool"]).exit_code == 5


def test_client_plans_then_calibrates_touch_by_touch(
    server: LiveServer, run: CliRunner, tmp_path: Path
) -> None:
    from scipy.spatial.transform import Rotation

    from app.kinematics.poses import pose_from_format

    with server.client() as http:
        robot = http.post("/v1/robots", json={"name": "kr16-guided"}).json()
        tool = http.post(f"/v1/robots/{robot['id']}/tools", json={"name": "probe"}).json()
    tcp, point = np.array([2.0, -1.0, 160.0]), np.array([780.0, 30.0, 240.0])
    down = Rotation.from_euler("x", 180.0, degrees=True)
    start = pose_to_format("kuka_abc", down.as_matrix(), point - down.apply(tcp))
    planned_csv = tmp_path / "plan.csv"
    planned = run.invoke(
        cli,
        ["plan", "--format", "kuka_abc", "--start", " ".join(f"{v}" for v in start),
         "--tcp", "2 -1 160", "--noise", "0.02", "--n", "8", "--csv", str(planned_csv)],
    )  # fmt: skip
    assert planned.exit_code == 0, planned.output
    assert "8 touches: predicted TCP 1-sigma" in planned.output
    # Columns named as the pendant names them (they were v1..v6), and the CSV says so too.
    assert "v1" not in planned.output
    for name in ("X", "Y", "Z", "A", "B", "C"):
        assert f" {name} " in planned.output
    header, *rows = list(csv.reader(planned_csv.open()))
    assert header == ["X", "Y", "Z", "A", "B", "C"]
    assert len(rows) == 8

    # The operator touches each planned orientation (the real tip on the point, 0.02 mm noise)
    # and types what the pendant shows, one line per touch, then finishes.
    rng = np.random.default_rng(5)
    lines = []
    for row in rows:
        R, _ = pose_from_format("kuka_abc", [float(v) for v in row])
        f = point - np.asarray(R) @ tcp + rng.normal(0.0, 0.02, 3)
        lines.append(" ".join(f"{v:.4f}" for v in pose_to_format("kuka_abc", R, f)))
    guided = run.invoke(
        cli,
        ["calibrate", tool["id"], "--guided", "--format", "kuka_abc", "--target", "0.05",
         "--note", "guided"],
        input="\n".join([*lines, "f"]) + "\n",
    )  # fmt: skip
    assert guided.exit_code == 0, guided.output
    assert "next: " in guided.output
    assert "4 touches: TCP" in guided.output
    assert "done" in guided.output
    assert "accepted: TCP (" in guided.output
    with server.client() as http:
        stored = http.get(f"/v1/tools/{tool['id']}/calibrations").json()["items"][0]
    assert stored["quality"]["n_poses"] == 8
    assert np.allclose(stored["tcp"]["position_mm"], tcp, atol=0.1)


def test_client_names_tools_activates_with_reasons_and_rolls_back_through_history(
    server: LiveServer, run: CliRunner, tmp_path: Path
) -> None:
    with server.client() as http:
        robots = [
            http.post("/v1/robots", json={"name": name, "vendor": "KUKA"}).json()
            for name in ("cell7-kr", "cell8-kr")
        ]
        made = {
            f"{r['name']}/{name}": http.post(
                f"/v1/robots/{r['id']}/tools", json={"name": name, "slot": slot}
            ).json()
            for r in robots
            for slot, name in ((1, "gripper"), (2, f"only-{r['name']}"))
        }
    tid = made["cell7-kr/only-cell7-kr"]["id"]

    fleet = run.invoke(cli, ["tools", "--q", "cell7"])
    assert fleet.exit_code == 0, fleet.output
    assert tid in fleet.output  # the id, whole, to paste into other commands

    # A unique name works where an id does; an ambiguous one lists robot/tool and id.
    for z in (150.0, 150.5, 151.0):
        body = {"method": "manual", "tcp": {"position_mm": [0.0, 0.0, z]}}
        with server.client() as http:
            http.post(f"/v1/tools/{tid}/calibrations", json=body).raise_for_status()
    noisy = simulate_touches(8, seed=3, touch_noise_mm=1.5)
    out_of_tol = run.invoke(
        cli,
        ["calibrate", "only-cell7-kr", str(_write_csv(tmp_path / "n.csv", noisy, "kuka_abc")),
         "--format", "kuka_abc"],
    )  # fmt: skip
    assert out_of_tol.exit_code == 3, out_of_tol.output  # version 4, stored, not active
    advice = 'tcpcal activate only-cell7-kr 4 --force --reason "<why>"'
    assert f"version 4 is stored, not active; to put it live anyway: {advice}" in " ".join(
        out_of_tol.output.split()
    )
    ambiguous = run.invoke(cli, ["history", "gripper"])
    assert ambiguous.exit_code == 2, ambiguous.output
    for key in ("cell7-kr/gripper", "cell8-kr/gripper"):
        assert key in ambiguous.output
        assert made[key]["id"] in ambiguous.output
    by_robot = run.invoke(cli, ["history", "cell8-kr/gripper"])
    assert by_robot.exit_code == 0, by_robot.output
    assert run.invoke(cli, ["history", "no-such-tool"]).exit_code == 5

    # Out of tolerance: refused without --force (exit 4, the server says how), then forced.
    refused = run.invoke(cli, ["activate", "only-cell7-kr", "4"])
    assert refused.exit_code == 4, refused.output
    said = " ".join(refused.output.split())
    assert "version 4 is stored as out_of_tolerance" in said
    assert f"nothing was changed; to put it live anyway: {advice}" in said
    assert '{"force"' not in said  # the CLI's flags, not the HTTP body
    assert run.invoke(cli, ["activate", "only-cell7-kr", "4", "--force"]).exit_code == 2
    forced = run.invoke(
        cli, ["activate", tid, "4", "--force", "--reason", "interim until the re-touch"]
    )
    assert forced.exit_code == 0, forced.output
    assert "version 4 is active" in forced.output
    history = run.invoke(cli, ["history", "cell7-kr/only-cell7-kr"])
    assert history.exit_code == 0, history.output
    assert "out_of_tolerance" in history.output
    assert "forced" in history.output
    assert "interim until the re-touch" in history.output
    trail = run.invoke(
        cli, ["audit", "--tool", "cell7-kr/only-cell7-kr", "--action", "version.activate"]
    )
    assert trail.exit_code == 0, trail.output
    assert "forced: interim until the re-touch (was v3)" in trail.output

    # Rollbacks walk back through what was active: 4 -> 3 -> 2 -> 1, then nothing left.
    walked = []
    for _ in range(3):
        rolled = run.invoke(cli, ["rollback", "only-cell7-kr", "--reason", "undo"])
        assert rolled.exit_code == 0, rolled.output
        walked.append(rolled.output.split("version ")[-1].split()[0])
    assert walked == ["3", "2", "1"]
    assert run.invoke(cli, ["rollback", "only-cell7-kr"]).exit_code == 4
