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
    secret_key: SecretStr | None = Field(
        default=None,
        description="encrypts controller passwords at rest (any long random string; keep it "
        "out of the database and its backups); a password cannot be stored while it is unset",
    )
    reconcile_interval_s: float = Field(
        default=0.0,
        ge=0,
        description="reconcile every robot that has a controller this often (seconds); 0: never",
    )
    reconcile_concurrency: int = Field(
        default=8,
        ge=1,
        le=256,
        description="controllers a reconcile round reads at once at least (threads, one "
        "controller connection each); each round reads as many more as its robots need for "
        "their reads to end within half the interval (robots x the reads' median time / half "
        "the interval, at most 64), and a read still going after 4 times that median (0.25 s "
        "to half the interval) holds no place: a controller that hangs delays no other robot",
    )
    public_url: str | None = Field(
        default=None,
        description="The server's URL as technicians and cell PCs reach it (e.g. "
        "https://tcpcal.plant.example), written into controller files' headers; default: "
        "the URL each request came to.",
    )
    stale_days: float = Field(
        default=180.0,
        gt=0,
        description="a tool with no calibration and no check for this many days is flagged "
        "`stale` in the fleet list",
    )
    corrections_alert: int = Field(
        default=3,
        ge=0,
        description="a tool corrected by re-checks more than this many times in 30 days is "
        "flagged `frequent_corrections` in the fleet list (a tool that keeps getting hit)",
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
