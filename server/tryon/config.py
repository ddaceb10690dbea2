"""Service settings, read from the environment (prefix ``TRYON_``)."""

from __future__ import annotations

from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict


class Settings(BaseSettings):
    """Everything the service reads from its environment.

    ``TRYON_DATA_DIR``: where the garment catalogue (SQLite index + arrays) lives.
    ``TRYON_ADMIN_TOKEN``: bearer token for catalogue writes; unset means writes are refused.
    """

    model_config = SettingsConfigDict(env_prefix="TRYON_", extra="ignore")

    data_dir: Path = Field(default=Path("data"), description="catalogue cache directory")
    admin_token: str | None = Field(default=None, description="bearer token for catalogue writes")
    web_dir: Path = Field(
        default=Path(__file__).resolve().parents[2] / "web",
        description="the page's static files (index.html, app code, node_modules/three)",
    )
    max_upload_bytes: int = Field(default=50 * 1024 * 1024, ge=1, description="largest garment upload, bytes")
    max_faces: int = Field(default=400_000, ge=1, description="largest garment mesh, faces")
    sim_workers: int = Field(default=2, ge=1, le=64, description="simulations run at once")
    sim_queue: int = Field(default=2, ge=0, le=256, description="simulations waiting for a worker before refusing")
    sim_wall_limit_s: float = Field(default=60.0, gt=0, description="wall-clock limit per simulation, s")
    result_cache_size: int = Field(default=32, ge=0, description="try-on results kept in memory")

    def ensure_dirs(self) -> None:
        self.data_dir.mkdir(parents=True, exist_ok=True)


def get_settings() -> Settings:
    return Settings()
