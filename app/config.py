"""Settings from TCPCAL_* environment variables (pydantic-settings)."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from pydantic import Field, SecretStr
from pydantic_settings import BaseSettings, SettingsConfigDict

DEFAULT_SQLITE_PATH = Path("var") / "tcpcal.sqlite3"


class Settings(BaseSettings):
    """Runtime configuration; every field can be set as TCPCAL_<NAME>."""

    model_config = SettingsConfigDict(env_prefix="TCPCAL_", extra="ignore")

    database_url: str = Field(
        default=f"sqlite:///{DEFAULT_SQLITE_PATH}",
        description="SQLAlchemy URL; SQLite file by default, postgresql+psycopg://... for a fleet",
    )
    bootstrap_admin_key: SecretStr | None = Field(
        default=None, description="When set, this key exists with admin scope (stored hashed)."
    )
    max_body_bytes: int = Field(default=1024 * 1024, gt=0, description="Largest request body.")
    idempotency_ttl_hours: float = Field(default=24.0, gt=0)
    solve_processes: int | None = Field(
        default=None,
        ge=0,
        description="processes that solve /v1/solve bodies off the event loop (per server "
        "worker); default: one per core but one (the event loop's); 0 solves in the request's "
        "thread",
    )
    public_url: str | None = Field(
        default=None,
        description="The server's URL as technicians and cell PCs reach it (e.g. "
        "https://tcpcal.plant.example), written into controller files' headers; default: "
        "the URL each request came to.",
    )
    problem_type_base: str = Field(
        default="/problems", description="Prefix of the `type` URI of problem documents."
    )

    def problem_type(self, kind: str) -> str:
        """The `type` URI of a problem kind, e.g. /problems/degenerate-poses."""
        return f"{self.problem_type_base.rstrip('/')}/{kind}"


@lru_cache
def get_settings() -> Settings:
    """The process-wide settings (read once; tests clear the cache)."""
    return Settings()
