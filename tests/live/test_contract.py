"""The contract fuzzed: schemathesis `--checks all`, stateful phase included, against a live
server; any failure fails the test. (The coverage phase is left out: it sends header values
that break the header's own pattern as if they were valid.)

On one database, PostgreSQL when the suite has it: the two backends are each fuzzed in process
by tests/api/test_schemathesis.py, and this test is about the served contract (uvicorn, the
middleware, the stateful links), which the database does not change. On both it cost 27 s more
of `make test`."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from testbed.live_server import fresh_database, live_server
from tests.conftest import ONE_BACKEND, PG_URL

pytestmark = pytest.mark.live
REPO = Path(__file__).resolve().parents[2]
CONTRACT = REPO / "tests" / "contract"
MAX_EXAMPLES = 15
SEED = 20261123


@pytest.mark.parametrize("backend", [ONE_BACKEND])
def test_schemathesis_all_checks_and_stateful_find_nothing(backend: str, tmp_path: Path) -> None:
    # One worker: schemathesis sends one request at a time, and the workers' sharing of a
    # server is the subject of tests/live/test_operations.py, not of the contract.
    with fresh_database(backend, tmp_path, PG_URL) as url, live_server(url, workers=1) as srv:
        env = {**os.environ, "SCHEMATHESIS_HOOKS": "tests.contract.hooks", "PYTHONPATH": str(REPO)}
        done = subprocess.run(
            [
                str(Path(sys.executable).parent / "schemathesis"),
                "--config-file",
                str(CONTRACT / "schemathesis.toml"),
                "run",
                f"{srv.url}/openapi.json",
                "--checks",
                "all",
                "--phases",
                "examples,fuzzing,stateful",
                # Deploying, reconciling, reading the pose and capturing a touch or a check
                # connect to the controller a PUT stored: with fuzzed hosts that would be
                # traffic to addresses off this machine, and an unreachable one is a 502. So no
                # controller is ever stored here (the PUT excluded, and with it every route
                # that reads one); they are tested against the controller simulators
                # (tests/api/test_deployments.py, test_capture_controllers.py,
                # test_controller_config.py, and the in-process fuzzing's fresh database per
                # operation).
                "--exclude-path-regex",
                "/(deployments|reconcile|controller|controller/pose)$",
                "--max-examples",
                str(MAX_EXAMPLES),
                "--seed",
                str(SEED),
                "--header",
                f"Authorization: Bearer {srv.admin_key}",
                "--no-color",
            ],
            cwd=REPO,
            env=env,
            capture_output=True,
            text=True,
            timeout=900,
        )
    report = done.stdout[-6000:] + done.stderr[-2000:]
    assert done.returncode == 0, report
    assert (
        "No issues found" in done.stdout or " 0 failures" in done.stdout or "passed" in done.stdout
    ), report
