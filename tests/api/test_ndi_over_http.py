"""The real NDI pivot recordings submitted over HTTP exactly as the tracker wrote them.

Each row's Tx,Ty,Tz,Q0,Qx,Qy,Qz is an `xyz_wxyz` pose. Every 50th OK frame is used (the
stream's consecutive frames share their errors; see tests/solvers/test_ndi_pivot.py)."""

from __future__ import annotations

import csv

import numpy as np

from app.jsontypes import JsonObject
from tests.conftest import Api
from tests.realdata import NDI_PIVOT

DATA = NDI_PIVOT


def _rows(name: str) -> list[tuple[str, list[float]]]:
    with (DATA / name).open(newline="") as fh:
        reader = csv.reader(fh)
        next(reader)
        return [(r[4], [float(x) for x in (*r[9:12], *r[5:9])]) for r in reader]


def _solve(api: Api, poses: list[list[float]]) -> JsonObject:
    response = api.post(
        "/v1/solve", {"method": "xyz_npoint", "format": "xyz_wxyz", "poses": poses}, scope="read"
    )
    assert response.status_code == 200, response.text
    return dict(response.json())


def test_both_recordings_agree_over_http(api: Api) -> None:
    tips, sigmas = [], []
    for name in ("pivot_2.csv", "pivot_3.csv"):
        ok = [pose for state, pose in _rows(name) if state == "OK"][::50]
        result = _solve(api, ok)
        assert result["quality"]["rms_mm"] < 0.5
        tips.append(np.asarray(result["tcp"]["position_mm"]))
        sigmas.append(np.asarray(result["quality"]["tcp_sigma_mm"]))
    combined = np.hypot(sigmas[0], sigmas[1])
    assert np.all(np.abs(tips[0] - tips[1]) <= 3 * combined)
    assert np.linalg.norm(tips[0] - tips[1]) < 1.0


def test_a_row_that_is_not_ok_is_refused(api: Api) -> None:
    # Both recordings hold only OK rows; a tracker that loses the tool writes a row like this
    # one (State "Missing", every value about -3.7e28). Submitted as is, it must be refused.
    rows = _rows("pivot_2.csv")
    assert {state for state, _ in rows} == {"OK"}
    missing = [-3.7e28] * 7
    poses = [*[pose for _, pose in rows][::50][:10], missing]
    response = api.post(
        "/v1/solve", {"method": "xyz_npoint", "format": "xyz_wxyz", "poses": poses}, scope="read"
    )
    assert response.status_code == 422
    problem = response.json()
    assert problem["type"].rsplit("/", 1)[1] in {"out-of-range", "invalid-rotation"}
    assert problem["errors"][0]["loc"][:3] == ["body", "poses", 10]
    assert "NaN" not in response.text
