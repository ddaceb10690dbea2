"""``POST /api/tryon``: drape a catalogue garment on a body built from measurements (SPEC section 6).

``prepare_tryon`` and ``run_tryon`` are plain functions (catalogue + validated request in, body / model /
settings or the result out) so the WebSocket route can run the same try-on with its own ``on_frame``.
The simulation runs on the app's simulation pool (worker threads; the numba kernels release the GIL),
never on the event loop.
"""

from __future__ import annotations

import json
import time

import numpy as np
from fastapi import APIRouter, HTTPException, Query, Request, status
from fastapi.responses import JSONResponse, Response

from tryon.api.deps import CatalogueDep
from tryon.api.export import MEDIA_TYPES, mesh_bytes, mesh_json
from tryon.api.pool import CachedTryOn, PoolFull, busy_response_headers, get_pool, get_result_cache, tryon_key
from tryon.api.schemas.bodies import to_body_params
from tryon.api.schemas.tryon import MeshFormatTryOn, TryOnOut, TryOnRequest
from tryon.body.build import build_body
from tryon.body.types import Body
from tryon.garment.catalogue import Catalogue
from tryon.garment.model import GarmentModel
from tryon.sim.run import FrameCallback, TryOnResult, drape
from tryon.sim.settings import SimSettings

router = APIRouter(tags=["tryon"])


def prepare_tryon(catalogue: Catalogue, request: TryOnRequest) -> tuple[Body, GarmentModel, SimSettings]:
    """The body, the garment model (at the requested simplification) and the settings of a request.
    KeyError if the garment is not in the catalogue."""
    if catalogue.get(request.garment_id) is None:
        raise KeyError(request.garment_id)
    settings = request.settings.to_settings()
    model = catalogue.model(request.garment_id, settings.simplification)
    measurements, pose = to_body_params(request.measurements, request.pose)
    return build_body(measurements, pose), model, settings


def run_tryon(catalogue: Catalogue, request: TryOnRequest, on_frame: FrameCallback | None = None) -> TryOnResult:
    """Prepare and drape one try-on (blocking: call it from a worker thread)."""
    return simulate(catalogue, request, on_frame).result


def body_mesh(body: Body) -> dict:
    """What a cached try-on keeps of its body (``CachedTryOn.body``): mesh and achieved measurements."""
    return {"vertices": body.vertices, "faces": body.faces, "achieved": body.achieved}


def simulate(catalogue: Catalogue, request: TryOnRequest, on_frame: FrameCallback | None = None) -> CachedTryOn:
    """Prepare and drape one try-on (blocking), kept as the result cache keeps it."""
    body, model, settings = prepare_tryon(catalogue, request)
    return CachedTryOn(result=drape(body, model, settings, on_frame), body=body_mesh(body), settings=settings)


def result_json(result: TryOnResult, cached_answer_s: float | None = None) -> dict:
    """The JSON answer (``TryOnOut``): the fitted garment and the metrics with the per-vertex strain.

    cached_answer_s: for a result served from the cache, the seconds this answer took: it becomes
    ``wall_seconds`` (with ``cached: true``), and the run's own time ``simulation_wall_seconds``."""
    m = result.metrics
    metrics = {
        "steps": int(m["steps"]),
        "sim_seconds": float(m["sim_seconds"]),
        "wall_seconds": float(m["wall_seconds"]) if cached_answer_s is None else round(cached_answer_s, 4),
        "simulation_wall_seconds": float(m["wall_seconds"]),
        "cached": cached_answer_s is not None,
        "rest_reached": bool(m["rest_reached"]),
        "penetrating_vertices": int(m["penetrating_vertices"]),
        "max_penetration_mm": round(float(m["max_penetration_mm"]), 3),
        "body_through_vertices": int(m["body_through_vertices"]),
        "max_body_through_mm": round(float(m["max_body_through_mm"]), 3),
        "max_strain": round(float(m["max_strain"]), 5),
        "strain": np.round(result.strain, 4).tolist(),
        "display_max_strain": round(float(m["display_max_strain"]), 5),
        "strain_by_kind": m.get("strain_by_kind", {}),
        "too_tight": m.get("too_tight", {}),
        "openings_on_limbs": m.get("openings_on_limbs"),
        "limb_openings": m.get("limb_openings", []),
        "slid_cm": round(float(m["slid_cm"]), 1),
        "stays_up": bool(m["stays_up"]),
        "sized_to_body": bool(m.get("sized_to_body", False)),
        "pose": m.get("pose", {}),
    }
    return {"garment": mesh_json(result.vertices, result.faces), "metrics": metrics}


def strain_colours(strain: np.ndarray, limit: float) -> np.ndarray:
    """RGBA uint8 per vertex: blue (no strain) -> green -> red (at the structural limit or beyond)."""
    t = np.clip(np.asarray(strain, float) / max(limit, 1e-9), 0.0, 1.0)
    rgb = np.stack([np.clip(2 * t - 0.5, 0, 1), 1 - np.abs(2 * t - 1), np.clip(1 - 2 * t, 0, 1)], axis=1)
    return np.concatenate([(rgb * 255).astype(np.uint8), np.full((len(t), 1), 255, np.uint8)], axis=1)


@router.post(
    "/tryon",
    response_model=TryOnOut,
    responses={404: {"description": "unknown garment"}, 422: {"description": "a field is out of range"},
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
    """Drape the garment on the body; answer the fitted garment and the fit metrics. A request equal to an
    earlier one (REST or WebSocket) is answered from the result cache, saying ``cached: true``."""
    started = time.perf_counter()
    if catalogue.get(body.garment_id) is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"no garment with id {body.garment_id!r}")
    pool = get_pool(request.app)
    guard = pool.guard()
    cache, key = get_result_cache(request.app), tryon_key(body)
    hit = cache.get(key)  # the same request again: the stored final state (shared with WS /ws/tryon)
    try:
        run = hit if hit is not None else await pool.run(simulate, catalogue, body, guard)
    except PoolFull as exc:
        raise HTTPException(status.HTTP_503_SERVICE_UNAVAILABLE, str(exc), headers=busy_response_headers(exc))
    except KeyError:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"no garment with id {body.garment_id!r}") from None
    except ValueError as exc:
        raise HTTPException(422, f"cannot run this try-on: {exc}") from None
    if hit is None and guard.stopped_by is None:  # cut-short runs are not kept
        cache.put(key, run)
    result = run.result
    out = result_json(result, None if hit is None else time.perf_counter() - started)
    if guard.stopped_by == "wall_limit":
        out["metrics"]["timed_out"] = True
    if format == "glb":
        colours = strain_colours(result.strain, SimSettings().strain_limit[0])
        data = mesh_bytes(result.vertices, result.faces, "glb", colours)
        summary = {k: v for k, v in out["metrics"].items() if k not in ("strain", "strain_by_kind")}
        return Response(content=data, media_type=MEDIA_TYPES["glb"],
                        headers={"X-Tryon-Metrics": json.dumps(summary)})
    return JSONResponse(out)
