"""One numbering for people: a sentence names touches (poses, sweeps, directions) from 1, as a
technician counts them on the pendant; JSON index fields (`quality.outliers`, a session's
`outliers`, `loc`, the path of DELETE .../poses/{index}) stay 0-based indexes into the
request's arrays."""

from __future__ import annotations

from collections.abc import Iterable


def number(index: int) -> int:
    """The number a person reads for the 0-based `index`."""
    return int(index) + 1


def numbered(noun: str, indices: Iterable[int]) -> str:
    """E.g. "touch 5", "touches 2, 5 and 7" for the 0-based `indices` (noun singular)."""
    numbers = [str(number(i)) for i in indices]
    if len(numbers) == 1:
        return f"{noun} {numbers[0]}"
    plural = noun + ("es" if noun.endswith(("ch", "sh", "s", "x")) else "s")
    if not numbers:
        return f"no {plural}"
    return f"{plural} {', '.join(numbers[:-1])} and {numbers[-1]}"
