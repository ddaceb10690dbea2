"""``POST /api/tryon``: drape a catalogue garment on a body built from measurements (SPEC section 6).

The try-on itself is ``service.simulate`` (shared with the WebSocket and the size advice); it runs on the
app's simulation pool (worker threads; the numba kernels release the GIL), never on the event loop. A
request equal to an earlier one (REST or WebSocket) is answered from the result cache.
"""

from __future__ import annotations

import json
import time

from fastapi import APIRouter, HTTPException, Query, Request, status
from fastapi.responses import JSONResponse, Response

from tryon.api.deps import CatalogueDep
from tryon.api.export import MEDIA_TYPES
from tryon.api.outfits import check_garments
from tryon.api.pool import PoolFull, busy_response_headers, get_pool, get_result_cache, tryon_key
from tryon.api.schemas.tryon import MeshFormatTryOn, OutfitOut, TryOnOut, TryOnRequest
from tryon.api.service import motion_glb, motion_json, result_glb, result_json, simulate

router = APIRouter(tags=["tryon"])


@router.post(
    "/tryon",
    response_model=TryOnOut | OutfitOut,
    responses={404: {"description": "unknown garment"},
               422: {"description": "a field is out of range, or an outfit's garment_ids cannot be worn together"},
               503: {"description": "every simulation worker is busy; retry after Retry-After seconds"},
               200: {"content": {"model/gltf-binary": {}}}},
)
async def tryon(
    request: Request,
    body: TryOnRequest,
    catalogue: CatalogueDep,
    format: MeshFormatTryOn = Query("json", description="json (mesh + metrics) or glb (the fitted garment, "
                                                         "vertex colours by strain; metrics in X-Tryon-Metrics)"),
):
    """Drape the garment (or the outfit: ``garment_ids``) on the body; answer the fitted garment(s) and the fit
    metrics. A request equal to an earlier one (REST or WebSocket) is answered from the result cache, saying
    ``cached: true``. An outfit's GLB holds each garment as a node of its own. A motion (``poses``) is draped
    pose after pose; its GLB holds the garment and the body with one morph target per later pose and an
    animation through them (one second per pose), its JSON each pose's metrics (``poses``)."""
    started = time.perf_counter()
    check_garments(catalogue, body)
    pool = get_pool(request.app)
    guard = pool.guard()
    cache, key = get_result_cache(request.app), tryon_key(body, catalogue)
    hit = cache.get(key)  # the same request again: the stored final state (shared with WS /ws/tryon)
    try:
        run = hit if hit is not None else await pool.run(simulate, catalogue, body, guard)
    except PoolFull as exc:
        raise HTTPException(status.HTTP_503_SERVICE_UNAVAILABLE, str(exc), headers=busy_response_headers(exc))
    except KeyError as exc:  # deleted meanwhile
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"no garment with id {exc.args[0]!r}") from None
    except ValueError as exc:
        raise HTTPException(422, f"cannot run this try-on: {exc}") from None
    if hit is None and guard.stopped_by is None:  # cut-short runs are not kept
        cache.put(key, run)
    result = run.result
    cached_s = None if hit is None else time.perf_counter() - started
    out = motion_json(run, cached_s) if body.poses is not None else result_json(result, cached_s)
    if guard.stopped_by == "wall_limit":
        out["metrics"]["timed_out"] = True
    if format == "glb":
        data = motion_glb(run, run.body["faces"]) if body.poses is not None else result_glb(result)
        summary = {k: v for k, v in out["metrics"].items() if k not in ("strain", "strain_by_kind")}
        return Response(content=data, media_type=MEDIA_TYPES["glb"],
                        headers={"X-Tryon-Metrics": json.dumps(summary)})
    return JSONResponse(out)
