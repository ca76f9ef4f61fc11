"""HTTP for API keys (admin)."""

from __future__ import annotations

from fastapi import APIRouter, Response
from starlette.convertors import StringConvertor, register_url_convertor

from app.api.deps import AdminKey, ReadKey, SessionDep
from app.api.params import DEFAULT_PAGE, Cursor, Limit, PathId
from app.api.shared import page
from app.schemas.common import Page
from app.schemas.keys import RESERVED_KEY_NAME, KeyCreate, KeyCreated, KeyMe, KeyOut
from app.services import keys

router = APIRouter(prefix="/v1/keys", tags=["keys"])


class _KeyIdConvertor(StringConvertor):
    """A key id's path segment: anything but `me`, the reserved word of the caller's own key,
    so /v1/keys/me is GET's only (DELETE and OPTIONS of it answer 405 naming GET, HEAD)
    and never the id route's."""

    regex = f"(?!{RESERVED_KEY_NAME}$)[^/]+"


register_url_convertor("key_id", _KeyIdConvertor())


@router.post("", status_code=201, response_model=KeyCreated)
def create_key(body: KeyCreate, session: SessionDep, key: AdminKey) -> KeyCreated:
    """Create an API key of a scope, limited to robot cells when `cells` is given (it then
    finds only those cells' robots and their tools: any other answers 404 as if absent);
    the key is shown in this answer only (stored as a hash). A key limited to cells creates
    keys limited to some of its cells only."""
    row, secret = keys.create_key(
        session, name=body.name, scope=body.scope, cells=body.cells, actor=key
    )
    return KeyCreated.model_validate(
        {**KeyOut.model_validate(row, from_attributes=True).model_dump(), "key": secret},
        from_attributes=True,
    )


@router.get("", response_model=Page[KeyOut])
def list_keys(
    session: SessionDep, key: AdminKey, limit: Limit = DEFAULT_PAGE, cursor: Cursor = None
) -> Page[KeyOut]:
    """Every API key with its name, scope, prefix and revocation time (never the key itself)."""
    items, next_cursor = keys.list_keys(session, limit=limit, cursor=cursor, actor=key)
    return page(KeyOut, items, next_cursor)


@router.get("/me", response_model=KeyMe)
def who_am_i(key: ReadKey) -> KeyMe:
    """The key this request was made with: its id, name and scope (any valid key may ask; a
    client such as the console offers only what the scope allows)."""
    return KeyMe(id=key.key_id, name=key.name, scope=key.scope)


@router.delete("/{key_id:key_id}", status_code=204)
def revoke_key(key_id: PathId, session: SessionDep, key: AdminKey) -> Response:
    """Revoke a key: it is refused from the next request on."""
    keys.revoke_key(session, key_id=key_id, actor=key)
    return Response(status_code=204)
