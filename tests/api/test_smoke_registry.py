"""Robots and tools: CRUD, filters, pagination, archive semantics, ETags."""

from __future__ import annotations

from tests.conftest import Api


def test_robot_crud_and_filters(api: Api) -> None:
    a = api.robot("kr-1", vendor="KUKA", cell="c1")
    api.robot("kr-2", cell="c2")
    listed = api.get("/v1/robots?cell=c1").json()
    assert [r["name"] for r in listed["items"]] == ["kr-1"]
    assert listed["next_cursor"] is None
    patched = api.patch(f"/v1/robots/{a['id']}", {"model": "KR 16"}).json()
    assert patched["model"] == "KR 16"
    assert patched["vendor"] == "KUKA"
    assert api.get("/v1/robots?name=kr-2").json()["items"][0]["cell"] == "c2"
