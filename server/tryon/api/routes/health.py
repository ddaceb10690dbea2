"""GET /api/health."""

from __future__ import annotations

from fastapi import APIRouter

from tryon import __version__

router = APIRouter(tags=["health"])


@router.get("/health")
def health() -> dict:
    """Liveness: answers at once, even while simulations run."""
    return {"status": "ok", "version": __version__}
