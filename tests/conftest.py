"""Shared fixtures: app factory with a temporary data dir, and a real ``tryon serve`` process."""

from __future__ import annotations

import contextlib
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import httpx
import pytest

from tryon.api.warmup import warm_up
from tryon.bench.live import serving
from tryon.config import Settings
from tryon.garment.catalogue import Catalogue

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


HANG_S = 120.0  # the longest a wait for the shared server may take: a guard against a hang, not a limit


@dataclass
class Shop:
    """A catalogue stocked on the shared server for one test module: ``add`` ingests a garment into the
    server's data directory (the served process reads the catalogue on each request)."""

    catalogue: Catalogue
    tag: str

    def add(self, source: Path | str | bytes, filename: str | None = None, **ingest) -> str:
        """Ingest ``source`` (a path, OBJ text or bytes; ``ingest``: ``Catalogue.ingest``'s keywords); its id.
        The file starts with a comment naming the module, so that each module's entries have ids of their own
        and the server's result cache answers a module nothing another one asked for."""
        if isinstance(source, Path):
            filename, source = filename or source.name, source.read_bytes()
        data = source.encode() if isinstance(source, str) else source
        return self.catalogue.ingest(f"# {self.tag}\n".encode() + data, filename=filename, **ingest).id


@dataclass
class SharedServer:
    """The one ``tryon serve`` process of the session's end-to-end tests (browser and WebSocket); each module
    stocks its own catalogue (``stocked``)."""

    url: str
    data_dir: Path

    @property
    def ws(self) -> str:
        return "ws" + self.url[len("http"):] + "/ws/tryon"

    def wait_idle(self) -> dict:
        """The pool's counters once no simulation runs or waits (polled; ``HANG_S`` guards against a hang)."""
        deadline = time.monotonic() + HANG_S
        while True:
            sims = httpx.get(f"{self.url}/api/health", timeout=HANG_S).json()["simulations"]
            if sims["running"] == 0 and sims["waiting"] == 0:
                return sims
            assert time.monotonic() < deadline, f"the shared server is still busy after {HANG_S:.0f} s: {sims}"
            time.sleep(0.05)

    def _empty(self, catalogue: Catalogue) -> None:
        self.wait_idle()
        for meta in catalogue.list():
            catalogue.delete(meta.id)

    @contextlib.contextmanager
    def stocked(self, tag: str):
        """An empty catalogue on an idle server for a module to fill (yields a ``Shop``); emptied after."""
        catalogue = Catalogue(self.data_dir)
        self._empty(catalogue)
        try:
            yield Shop(catalogue, tag)
        finally:
            self._empty(catalogue)


@contextlib.contextmanager
def served_here(app):
    """``app`` served by uvicorn on a thread of this process (its kernels warm: ``warm_kernels``); its URL. A
    real server whose insides a test can hold (a job on its pool, a patched step) to make a state certain."""
    import uvicorn

    from tryon.bench.live import free_port

    port = free_port()
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 120  # a guard against a hang, not a measured limit
    while not server.started or httpx.get(url + "/api/health").status_code != 200:
        assert thread.is_alive() and time.monotonic() < deadline, "the service did not start"
        time.sleep(0.05)
    try:
        yield url
    finally:
        server.should_exit = True
        thread.join(timeout=120)


@pytest.fixture(scope="session")
def shared_server(tmp_path_factory) -> SharedServer:
    """ONE real uvicorn server (``tryon serve``, its default pool) for the session's browser and live
    WebSocket tests, instead of one per module."""
    data = tmp_path_factory.mktemp("shared-server") / "data"
    Catalogue(data)  # the index exists before the server opens it
    with serve_process(data) as url:
        yield SharedServer(url, data)


@pytest.fixture(scope="module")
def live_server(shared_server: SharedServer) -> str:
    """The shared server's URL, with an empty catalogue (``test_foundation``)."""
    with shared_server.stocked("live_server"):
        yield shared_server.url


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
