"""The active-TCP read authenticates and reads in one statement, caching nothing: a revoked
key is refused by the very next request, a new activation is served at once, and every
refusal is the same problem document as on any other route."""

from __future__ import annotations

from tests.conftest import Api


def test_the_hot_read_sees_revocations_and_activations_at_once(api: Api) -> None:
    tool = api.tool(api.robot("kr")["id"], slot=2)
    tid = tool["id"]
    for z in (150, 151):
        api.post(
            f"/v1/tools/{tid}/calibrations",
            json={"method": "manual", "tcp": {"position_mm": [0, 0, z]}},
        )
    created = api.post("/v1/keys", json={"name": "cell-7", "scope": "read"}).json()
    reader = {"Authorization": f"Bearer {created['key']}"}
    first = api.client.get(f"/v1/tools/{tid}/tcp", headers=reader)
    assert first.status_code == 200
    assert first.json()["tcp"]["position_mm"] == [0.0, 0.0, 151.0]

    api.post(f"/v1/tools/{tid}/versions/1/activate")
    again = api.client.get(
        f"/v1/tools/{tid}/tcp", headers={**reader, "If-None-Match": first.headers["etag"]}
    )
    assert again.status_code == 200  # not 304: the activation is served by the next read
    assert again.json()["version"] == 1

    assert api.delete(f"/v1/keys/{created['id']}").status_code == 204
    revoked = api.client.get(f"/v1/tools/{tid}/tcp", headers=reader)
    assert revoked.status_code == 401
    assert revoked.headers["content-type"].startswith("application/problem+json")
    assert "revoked" in revoked.json()["detail"]

    assert api.client.get(f"/v1/tools/{tid}/tcp").status_code == 401  # no header
    bad = {"Authorization": "Bearer not-a-key"}
    assert api.client.get("/v1/tools/nope/tcp", headers=bad).status_code == 401  # key first
    assert api.get("/v1/tools/00000000-0000-0000-0000-000000000000/tcp").status_code == 404
    fresh = api.tool(api.robot("kr2")["id"])
    none = api.get(f"/v1/tools/{fresh['id']}/tcp")
    assert none.status_code == 404
    assert none.json()["type"].endswith("/no-active-version")
    api.delete(f"/v1/tools/{tid}")
    archived = api.get(f"/v1/tools/{tid}/tcp")
    assert archived.status_code == 404
    assert archived.json()["type"].endswith("/archived")
