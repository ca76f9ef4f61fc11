"""Changes the plant must hear of, made through the API for the publisher tests (MQTT and
OPC UA) and the activation tests: a version stored out of tolerance and forced live with a
reason."""

from __future__ import annotations

from typing import Any

from testbed.sim.touches import simulate_touches
from tests.api.touches import as_poses
from tests.conftest import Api


def out_of_tolerance_version(api: Api, tool_id: str) -> int:
    """Store a calibration whose touches are too noisy (1.5 mm): a version stored
    out_of_tolerance and not activated; its number."""
    bad = simulate_touches(8, seed=2, touch_noise_mm=1.5)
    response = api.post(
        f"/v1/tools/{tool_id}/calibrations",
        {"method": "xyz_npoint", "format": "xyz_wxyz", "poses": as_poses(bad)},
        scope="calibrate",
    )
    assert response.status_code == 201, response.text
    body: dict[str, Any] = response.json()
    assert (body["status"], body["active"]) == ("out_of_tolerance", False)
    return int(body["version"])


def force(api: Api, tool_id: str, version: int, reason: str) -> None:
    """Activate an out-of-tolerance version with force and a reason (API.md v1.2)."""
    response = api.post(
        f"/v1/tools/{tool_id}/versions/{version}/activate",
        {"force": True, "reason": reason},
        scope="calibrate",
    )
    assert response.status_code == 200, response.text


def rollback(api: Api, tool_id: str) -> None:
    """Roll back without a reason."""
    response = api.post(f"/v1/tools/{tool_id}/rollback", scope="calibrate")
    assert response.status_code == 200, response.text
