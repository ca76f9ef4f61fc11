"""Entity tags: one parser for If-Match / If-None-Match lists (RFC 9110 section 13.1)."""

from __future__ import annotations


def _tags(header: str) -> set[str]:
    return {tag.strip() for tag in header.split(",") if tag.strip()}


def if_match_ok(header: str | None, etag: str) -> bool:
    """If-Match: strong comparison; absent header or "*" passes."""
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
