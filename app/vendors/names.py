"""Tool names made safe for a controller: its character set, its length, its reserved words.

A tool's name is user input (any Unicode, up to 200 characters); each controller stores names
and comments in a narrow character set (KSS and TP files are single-byte code pages,
condition files and TP remarks are ASCII on the pendant) and a fixed length. What is kept:
letters with their accents taken off (NFKD, "Düse" -> "Duse"), printable ASCII; what is
dropped: everything else (an emoji, a control character, a line break). Nothing here can start
a new program line.
"""

from __future__ import annotations

import re
import unicodedata
from collections.abc import Collection, Iterable


def ascii_text(text: str, limit: int, *, drop: str = "") -> str:
    """`text` as one line of printable ASCII without the characters in `drop`, at most `limit`
    characters, runs of spaces made one ("Düse 🔥 #2" -> "Duse #2")."""
    decomposed = unicodedata.normalize("NFKD", text)
    kept = "".join(
        ch if " " <= ch <= "~" and ch not in drop else " "
        for ch in decomposed
        if not unicodedata.combining(ch)
    )
    return " ".join(kept.split())[:limit].rstrip()


def identifier(
    text: str,
    limit: int,
    *,
    fallback: str,
    upper: bool = False,
    reserved: Collection[str] = (),
) -> str:
    """`text` as an identifier [A-Za-z][A-Za-z0-9_]* of at most `limit` characters: accents
    taken off, anything else an underscore, `fallback` in front when it would not start with a
    letter ("2nd" -> "t2nd"); a reserved word (compared without case) gets "_1" added."""
    plain = ascii_text(text, 10_000)
    ident = re.sub(r"[^A-Za-z0-9_]", "_", plain)
    ident = re.sub(r"_+", "_", ident).strip("_")
    if not ident or not ident[0].isalpha():
        ident = fallback + ident
    ident = ident[:limit].rstrip("_")
    if upper:
        ident = ident.upper()
    if ident.lower() in reserved:
        ident = ident[: limit - 2] + "_1"
    return ident


def unique(names: Iterable[str], limit: int) -> list[str]:
    """The names with a "_2", "_3" ... suffix (within `limit`) on each repeat (compared
    without case: RAPID and KRL names are case-insensitive)."""
    seen: set[str] = set()
    out: list[str] = []
    for name in names:
        candidate, n = name, 1
        while candidate.lower() in seen:
            n += 1
            suffix = f"_{n}"
            candidate = name[: limit - len(suffix)] + suffix
        seen.add(candidate.lower())
        out.append(candidate)
    return out


def file_stem(text: str, limit: int = 40) -> str:
    """`text` as a file name's stem: ASCII letters, digits, "-" and "_" ("tool" when none)."""
    stem = re.sub(r"[^A-Za-z0-9_-]+", "_", ascii_text(text, 10_000)).strip("_")
    return stem[:limit] or "tool"
