"""The try-on as the routes run it: the body, model and settings of a validated request, the drape (kept as
the result cache keeps it), and the JSON answer. Plain functions, shared by ``POST /api/tryon``, the
WebSocket (``live.py``), the size advice (``advice.py``) and the warm-up; a drape is blocking: call it from a
pool thread, never the event loop."""

from __future__ import annotations

import numpy as np

from tryon.api.export import mesh_json
from tryon.api.pool import CachedTryOn
from tryon.api.schemas.bodies import to_body_params
from tryon.api.schemas.tryon import TryOnRequest
from tryon.body.build import build_body
from tryon.body.types import Body
from tryon.garment.catalogue import Catalogue
from tryon.garment.model import GarmentModel
from tryon.sim.run import FrameCallback, TryOnResult, drape
from tryon.sim.settings import SimSettings


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
