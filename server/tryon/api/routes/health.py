"""GET /api/health."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

from tryon import __version__
from tryon.api.pool import get_pool, get_result_cache

router = APIRouter(tags=["health"])


@router.get("/health", responses={503: {"description": "starting: the kernels are still being compiled or "
                                                      "loaded; retry in a second"}})
async def health(request: Request) -> JSONResponse:
    """Readiness and liveness: ``"status": "ok"`` (200) once the service can serve a request as fast as
    the tenth, ``"starting"`` (503) while its kernels warm up at start-up (``warmup``: state and seconds).
    Answers at once, even while simulations run (``async``: no thread hop; only counters are read).
    ``simulations``: the pool's running / waiting / capacity counters; ``result_cache``: its size."""
    warmup = request.app.state.warmup
    body = {
        "status": "ok" if warmup.ready else "starting",
        "version": __version__,
        "warmup": warmup.stats(),
        "simulations": get_pool(request.app).stats(),
        "result_cache": get_result_cache(request.app).stats(),
    }
    return JSONResponse(body, status_code=200 if warmup.ready else 503)
