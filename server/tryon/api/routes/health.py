"""GET /api/health."""

from __future__ import annotations

from fastapi import APIRouter, Request

from tryon import __version__
from tryon.api.pool import get_pool, get_result_cache

router = APIRouter(tags=["health"])


@router.get("/health")
async def health(request: Request) -> dict:
    """Liveness: answers at once, even while simulations run (``async``: no thread hop; only counters are
    read). ``simulations``: the pool's running / waiting / capacity counters; ``result_cache``: its size."""
    return {
        "status": "ok",
        "version": __version__,
        "simulations": get_pool(request.app).stats(),
        "result_cache": get_result_cache(request.app).stats(),
    }
