"""``POST /api/fit``: which size of a style fits this body (the drapes: ``tryon.api.advice``)."""

from __future__ import annotations

import time

from fastapi import APIRouter, HTTPException, Request, status
from fastapi.concurrency import run_in_threadpool

from tryon.api.advice import style_advice
from tryon.api.deps import CatalogueDep
from tryon.api.pool import PoolFull, busy_response_headers, get_pool, get_result_cache
from tryon.api.schemas.fit import FitOut, FitRequest

router = APIRouter(tags=["fit"])


@router.post("/fit", response_model=FitOut,
             responses={404: {"description": "unknown style"}, 422: {"description": "a field is out of range"},
                        503: {"description": "every simulation worker is busy; retry after Retry-After seconds"}})
async def fit(request: Request, body: FitRequest, catalogue: CatalogueDep) -> FitOut:
    """Drape the style's sizes on the body (concurrently on the simulation pool; sizes two or more sizes from
    the person's on the style's chart are not draped unless needed) and say which size to take, with each
    size's verdict, ease and reason. Every drape lands in the result cache under the key ``POST /api/tryon``
    of that size with the same measurements and pose uses."""
    started = time.perf_counter()
    entries = await run_in_threadpool(catalogue.style, body.style)
    if not entries:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"no style {body.style!r} (GET /api/styles lists them)")
    try:
        out = await run_in_threadpool(style_advice, get_pool(request.app), get_result_cache(request.app), catalogue,
                                      entries, body)
    except PoolFull as exc:
        raise HTTPException(status.HTTP_503_SERVICE_UNAVAILABLE, str(exc), headers=busy_response_headers(exc))
    return FitOut(**out, wall_seconds=round(time.perf_counter() - started, 3))
