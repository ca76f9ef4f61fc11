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

import pytest
import yaml

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


def test_alerts_use_only_metric_names_the_server_serves() -> None:
    """Each tcpcal_* name in the rules is one app/ defines (a renamed gauge would leave an
    alert that can never fire)."""
    app_text = "\n".join(p.read_text() for p in (RULES_DIR.parents[1] / "app").rglob("*.py"))
    names = set(re.findall(r"\btcpcal_[a-z_]+\b", RULES.read_text()))
    missing = {n for n in names if f'"{n}"' not in app_text}
    assert missing == set()
