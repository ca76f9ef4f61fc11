"""The alert rules in deploy/prometheus are valid and do what their unit tests say, checked
by Debian's promtool (package `prometheus`; `.ci/run` installs it). Without promtool these
tests are skipped on a workstation and fail under CI (`CI` or `TCPCAL_REQUIRE_BROWSER` set,
as for the browser tests): a missing tool must never pass a CI run silently."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path
from typing import get_args

import pytest
import yaml

from app.schemas.fleet import AttentionCode, FrameAttentionCode
from tests.conftest import Api

RULES_DIR = Path(__file__).resolve().parents[1] / "deploy" / "prometheus"
RULES = RULES_DIR / "tcpcal.rules.yml"
RULE_TESTS = RULES_DIR / "tcpcal.rules.test.yml"


def _promtool() -> str:
    found = shutil.which("promtool")
    if found:
        return found
    if os.environ.get("CI") or os.environ.get("TCPCAL_REQUIRE_BROWSER"):
        pytest.fail("promtool is missing: apt-get install prometheus (.ci/run does)")
    pytest.skip("promtool not installed (apt-get install prometheus)")


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [_promtool(), *args], cwd=RULES_DIR, capture_output=True, text=True, timeout=120
    )


def test_promtool_checks_the_rules() -> None:
    done = _run("check", "rules", RULES.name)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "SUCCESS" in done.stdout


def test_promtool_unit_tests_of_the_rules_pass() -> None:
    done = _run("test", "rules", RULE_TESTS.name)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "SUCCESS" in done.stdout


def test_promtool_test_rules_fails_when_a_rule_is_wrong(tmp_path: Path) -> None:
    """The unit tests can fail: with the drift alert's code misspelt they do."""
    broken = RULES.read_text().replace('code="controller_drifted"', 'code="controller_drift"')
    (tmp_path / RULES.name).write_text(broken)
    (tmp_path / RULE_TESTS.name).write_text(RULE_TESTS.read_text())
    done = subprocess.run(
        [_promtool(), "test", "rules", RULE_TESTS.name],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode != 0
    assert "TcpcalControllerDrifted" in done.stdout + done.stderr


def test_every_alert_has_a_unit_test_that_expects_it_to_fire() -> None:
    rules = yaml.safe_load(RULES.read_text())
    alerts = {r["alert"] for g in rules["groups"] for r in g["rules"] if "alert" in r}
    tests = yaml.safe_load(RULE_TESTS.read_text())["tests"]
    fired = {
        case["alertname"]
        for test in tests
        for case in test.get("alert_rule_test", [])
        if case.get("exp_alerts")
    }
    assert alerts - fired == set()


def test_alerts_use_only_metric_names_the_server_serves(api: Api) -> None:
    """Each tcpcal_* name in the rules is one the server's /metrics serves (a renamed gauge
    would leave an alert that can never fire). Read off /metrics, not app/'s text: the fleet's
    families are named by each subject's declaration (app.services.fleet.collector), and a
    family with no series still says its name (# TYPE)."""
    served = set(re.findall(r"^# TYPE (tcpcal_[a-z_]+) ", api.get("/metrics").text, re.M))
    names = set(re.findall(r"\btcpcal_[a-z_]+\b", RULES.read_text()))
    assert names - served == set()


#: The fleet's attention codes (tcpcal_tool_attention{code}) no alert fires on, and why;
#: every other code has its alert, so a code added to the fleet is judged here.
NOT_ALERTED = {
    "last_calibration_out_of_tolerance": "a calibration not activated: the TCP served is "
    "the active one (active_out_of_tolerance alerts when that one is bad)",
    "no_active_version": "a tool being set up: no TCP is served for it yet",
    "frequent_corrections": "each re-check corrected the TCP already; the fleet view and "
    "the audit trail show the tool that keeps getting hit",
}


#: A frame's attention codes (tcpcal_frame_attention{code}) no alert fires on, and why: the
#: frames' own `moving_in_*` alert; the codes a frame shares with a tool are, for now, on
#: the fleet view (GET /v1/frames) and the tcpcal_fleet_frames_attention counts only.
FRAME_NOT_ALERTED = {
    code: "shared with tools, alerted for tools only so far: GET /v1/frames and "
    "tcpcal_fleet_frames_attention show it"
    for code in get_args(FrameAttentionCode)
    if not code.startswith("moving_in_")
}


def test_every_attention_code_has_an_alert_or_a_reason_not_to() -> None:
    """The robot moving by an older version or by a TCP no version has (contract v1.3) was
    exported as tcpcal_tool_attention but fired no alert: each code now either has an alert
    or is in NOT_ALERTED with its reason. (A tool's controller state not_live is no fault:
    tcpcal_fleet_tools_controller_state{state="not_live"} counts such tools.)"""
    for family, code_type, not_alerted in (
        ("tcpcal_tool_attention", AttentionCode, NOT_ALERTED),
        ("tcpcal_frame_attention", FrameAttentionCode, FRAME_NOT_ALERTED),
    ):
        pattern = re.escape(family) + r'\{code="([a-z_]+)"\}'
        alerted = set(re.findall(pattern, RULES.read_text()))
        codes = set(get_args(code_type))
        assert alerted <= codes, (family, alerted - codes)
        assert not alerted & set(not_alerted), (family, alerted & set(not_alerted))
        assert codes - alerted == set(not_alerted), (family, codes - alerted - set(not_alerted))
