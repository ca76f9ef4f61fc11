"""A cursor over a controller's value text: the steps the KRL and RAPID readers share.

Both texts are aggregates of tokens with arbitrary spaces between them (KRL ``{X 1.0,Y
2.0}``, RAPID ``[[0,0,150],[1,0,0,0]]``); each reader (app.vendors.kuka.text,
app.vendors.abb.text) subclasses `Scanner` with its own grammar and its own `error` (a
ValueError naming the text).
"""

from __future__ import annotations


class Scanner:
    """A position in `text`; every failure raises `error` with the position and the text."""

    error: type[ValueError] = ValueError

    def __init__(self, text: str) -> None:
        self.text = text
        self.pos = 0

    def skip_spaces(self) -> None:
        while self.pos < len(self.text) and self.text[self.pos].isspace():
            self.pos += 1

    def peek(self) -> str:
        """The next character after any spaces ("" at the end), not consumed."""
        self.skip_spaces()
        return self.text[self.pos] if self.pos < len(self.text) else ""

    def expect(self, char: str) -> None:
        """Consume `char` (after any spaces), or raise naming what is there instead."""
        if self.peek() != char:
            found = self.text[self.pos : self.pos + 10] or "the end"
            raise self.error(f"expected {char!r} at {self.pos} of {self.text!r}, got {found!r}")
        self.pos += 1

    def token(self, stops: str) -> tuple[int, str]:
        """(where it starts, the text up to the next of `stops` or the end, stripped)."""
        start = self.pos
        while self.pos < len(self.text) and self.text[self.pos] not in stops:
            self.pos += 1
        return start, self.text[start : self.pos].strip()

    def finish(self, what: str) -> None:
        """Raise when anything but spaces follows the `what` just read."""
        self.skip_spaces()
        if self.pos != len(self.text):
            raise self.error(f"unexpected text after the {what}: {self.text[self.pos :]!r}")
