"""The baseline for bench.wrk_load: a bare FastAPI app answering a constant JSON."""

from __future__ import annotations

from fastapi import FastAPI

app = FastAPI()

CONSTANT = {"slot": 3, "version": 1, "tcp": {"position_mm": [0.0, 0.0, 150.0]}}


@app.get("/constant")
def constant() -> dict[str, object]:
    """The same small JSON every time: no auth, no database, no ETag."""
    return CONSTANT
