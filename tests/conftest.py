"""Shared fixtures: app factory with a temporary data dir, and a real ``tryon serve`` process."""

from __future__ import annotations

import contextlib
from pathlib import Path

import pytest

from tryon.api.warmup import warm_up
from tryon.bench.live import serving
from tryon.config import Settings

ROOT = Path(__file__).resolve().parents[1]
ADMIN_TOKEN = "test-admin-token"


@pytest.fixture(scope="session", autouse=True)
def warm_kernels() -> None:
    """Compile (or load from the disk cache) every kernel once for the whole session, as the service does
    at start-up: apps made in this process are ready at once, and served processes load a warm cache."""
    warm_up()


@pytest.fixture
def settings(tmp_path: Path) -> Settings:
    return Settings(data_dir=tmp_path / "data", admin_token=ADMIN_TOKEN)


@contextlib.contextmanager
def serve_process(data_dir: Path, env: dict | None = None, timeout_s: float = 120.0):
    """Run ``tryon serve`` on a free port; yield its base URL once ``/api/health`` says ok (its kernels warm:
    loaded from the disk cache that ``warm_kernels`` filled); stop it afterwards."""
    with serving(data_dir, {"TRYON_ADMIN_TOKEN": ADMIN_TOKEN, **(env or {})}, timeout_s, cwd=ROOT) as url:
        yield url


@pytest.fixture(scope="session")
def live_server(tmp_path_factory) -> str:
    """A real uvicorn server (``tryon serve``) shared by the session's end-to-end tests."""
    with serve_process(tmp_path_factory.mktemp("live-data")) as url:
        yield url


CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"]


@pytest.fixture(scope="session")
def browser():
    """Debian's headless Chromium driven by Playwright."""
    from playwright.sync_api import sync_playwright

    if not Path(CHROMIUM).exists():
        pytest.fail(f"{CHROMIUM} is missing: run `bash scripts/test.sh`, which installs it")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()
