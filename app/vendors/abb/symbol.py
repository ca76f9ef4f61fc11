"""Where an ABB tool lives: its PERS tooldata, named "TASK/MODULE/SYMBOL" (the tool's
``controller_symbol``). Plain ``re``: the API's schemas check a symbol with `SYMBOL_PATTERN`.
"""

from __future__ import annotations

import re

# RAPID identifiers: a letter, then letters, digits or underscores, at most 32 characters
# (ABB Technical reference manual - RAPID overview, "Identifiers").
_RAPID_IDENTIFIER = r"[A-Za-z][A-Za-z0-9_]{0,31}"
SYMBOL_PATTERN = re.compile(rf"^({_RAPID_IDENTIFIER})/({_RAPID_IDENTIFIER})/({_RAPID_IDENTIFIER})$")


def symbol_problem(symbol: str) -> str | None:
    """Why `symbol` is not a "TASK/MODULE/SYMBOL" RAPID path, in a sentence; None when it is."""
    if SYMBOL_PATTERN.match(symbol) is None:
        return (
            f'{symbol!r} is not "TASK/MODULE/SYMBOL" (three RAPID names of a letter then '
            'letters, digits or _, at most 32 characters each), e.g. "T_ROB1/user/tTorch"'
        )
    return None


def split_symbol(symbol: str) -> tuple[str, str, str]:
    """ "T_ROB1/user/tTorch" -> ("T_ROB1", "user", "tTorch"); ValueError naming the problem."""
    match = SYMBOL_PATTERN.match(symbol)
    if match is None:
        raise ValueError(symbol_problem(symbol))
    task, module, name = match.groups()
    return task, module, name
