"""Entity tags: one parser for If-Match / If-None-Match lists (RFC 9110 section 13.1)."""

from __future__ import annotations

#: An If-Match header: "*" or a list of entity tags as RFC 9110 section 8.8.3 writes them
#: (weak ones and other servers' included). Whatever does not parse is refused (422, naming the
#: header); a tag that parses but is not the tool's current one, a weak tag among them, fails
#: the precondition (412): If-Match compares strongly (section 13.1.1), and a weak tag cannot
#: match (a proxy that compresses may weaken our tag; the client learns it is stale, not that
#: its header is malformed).
IF_MATCH_PATTERN = r'^(\*|(W/)?"[!#-~]*"([ \t]*,[ \t]*(W/)?"[!#-~]*")*)$'
#: An If-None-Match header: "*" or a list of tags, weak (W/) ones included.
IF_NONE_MATCH_PATTERN = r'^(\*|(W/)?"[0-9a-f]{16,64}"( *, *(W/)?"[0-9a-f]{16,64}")*)$'


def _tags(header: str) -> set[str]:
    return {tag.strip() for tag in header.split(",") if tag.strip()}


def if_match_ok(header: str | None, etag: str) -> bool:
    """If-Match: strong comparison against our (strong) `etag`, so a weak tag in the header,
    written W/"...", never equals it; absent header or "*" passes."""
    if header is None:
        return True
    tags = _tags(header)
    return "*" in tags or etag in tags


def if_none_match_hit(header: str | None, etag: str) -> bool:
    """If-None-Match: weak comparison (a proxy may have weakened our tag with W/)."""
    if header is None:
        return False
    tags = {tag.removeprefix("W/") for tag in _tags(header)}
    return "*" in tags or etag.removeprefix("W/") in tags
