"""The FastAPI application factory: it only assembles routers, static files and state."""

from __future__ import annotations

from contextlib import asynccontextmanager

from fastapi import FastAPI
from fastapi.staticfiles import StaticFiles

from tryon import __version__
from tryon.api import errors
from tryon.api.routes import bodies, fabrics, fit, garments, health, styles, tryon, ws
from tryon.api.warmup import WarmUp
from tryon.config import Settings, get_settings


@asynccontextmanager
async def _lifespan(app: FastAPI):
    """Start the kernels' warm-up in the background; ``/api/health`` says "starting" (503) until it is done."""
    app.state.warmup.start()
    yield


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the app with ``settings`` (default: from the environment)."""
    settings = settings or get_settings()
    settings.ensure_dirs()
    app = FastAPI(title="tryon", version=__version__, docs_url="/api/docs", openapi_url="/api/openapi.json",
                  lifespan=_lifespan)
    app.state.settings = settings
    app.state.warmup = WarmUp()
    errors.install(app)

    for module in (health, bodies, garments, fabrics, styles, tryon, fit):
        app.include_router(module.router, prefix="/api")
    app.include_router(ws.router)

    three_dir = settings.web_dir / "node_modules" / "three"
    if three_dir.is_dir():
        app.mount("/vendor/three", StaticFiles(directory=three_dir), name="three")
    app.mount("/", StaticFiles(directory=settings.web_dir, html=True), name="web")
    return app
