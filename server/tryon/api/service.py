"""The try-on as the routes run it: the body, model and settings of a validated request, the drape (kept as
the result cache keeps it), and the JSON answer. Plain functions, shared by ``POST /api/tryon``, the
WebSocket (``live.py``), the size advice (``advice.py``) and the warm-up; a drape is blocking: call it from a
pool thread, never the event loop."""

from __future__ import annotations

import numpy as np

from tryon.api.export import mesh_bytes, mesh_json, morph_glb, scene_bytes
from tryon.api.outfits import outfit_models
from tryon.api.pool import CachedTryOn
from tryon.api.schemas.bodies import to_body_params
from tryon.api.schemas.tryon import TryOnRequest
from tryon.body.build import build_body
from tryon.body.params import Pose
from tryon.body.types import Body
from tryon.fit.advice import SizeAdvice, advise_size
from tryon.fit.verdict import length_notes
from tryon.garment.catalogue import Catalogue
from tryon.garment.model import GarmentModel
from tryon.sim.outfit import OutfitResult, drape_outfit, piece_categories
from tryon.sim.repose import redrape_if_off, repose
from tryon.sim.run import FrameCallback, TryOnResult, drape, settle
from tryon.sim.settings import SimSettings
from tryon.sim.start import start


def prepare_tryon(catalogue: Catalogue, request: TryOnRequest) -> tuple[Body, GarmentModel, SimSettings]:
    """The body, the garment model (at the requested simplification) and the settings of a request.
    KeyError if the garment is not in the catalogue."""
    if catalogue.get(request.garment_id) is None:
        raise KeyError(request.garment_id)
    settings = request.settings.to_settings()
    model = catalogue.model(request.garment_id, settings.simplification)
    measurements, pose = to_body_params(request.measurements, request.pose)
    return build_body(measurements, pose), model, settings


def run_tryon(catalogue: Catalogue, request: TryOnRequest,
              on_frame: FrameCallback | None = None) -> TryOnResult | OutfitResult:
    """Prepare and drape one try-on, a garment or an outfit (blocking: call it from a worker thread)."""
    return simulate(catalogue, request, on_frame).result


def body_mesh(body: Body) -> dict:
    """What a cached try-on keeps of its body (``CachedTryOn.body``): mesh and achieved measurements."""
    return {"vertices": body.vertices, "faces": body.faces, "achieved": body.achieved}


def simulate(catalogue: Catalogue, request: TryOnRequest, on_frame: FrameCallback | None = None) -> CachedTryOn:
    """Prepare and drape one try-on (blocking), kept as the result cache keeps it. An outfit's ``on_frame``
    gets one coarse array per garment, in layer order."""
    if request.outfit:
        body, models, settings = prepare_outfit(catalogue, request)
        result = judged(drape_outfit(body, models, settings, request.tuck, on_frame=on_frame), body, models)
        return CachedTryOn(result=result, body=body_mesh(body), settings=settings)
    if request.poses is not None:
        return simulate_motion(catalogue, request, on_frame)
    body, model, settings = prepare_tryon(catalogue, request)
    run = CachedTryOn(result=drape(body, model, settings, on_frame), body=body_mesh(body), settings=settings)
    # the size advice of this drape, kept for POST /api/fit's same body (``fit.advice.Drape.advice``)
    run.extra["advice"] = judge_sizes(run.result, body, [model])[0]
    return run


def judged(result: TryOnResult | OutfitResult, body: Body, models: list[GarmentModel]) -> TryOnResult | OutfitResult:
    """``result`` with each garment's one verdict in its metrics (``judge_sizes``)."""
    judge_sizes(result, body, models)
    return result


def judge_sizes(result: TryOnResult | OutfitResult, body: Body, models: list[GarmentModel]) -> list[SizeAdvice]:
    """Each garment's one verdict, put in its metrics (``verdict`` and ``verdict_reason``) and returned as its
    size advice: judged on the shown mesh as ``POST /api/fit`` judges a size (``fit.advice.advise_size``: too
    tight where, falls off, loose, its length; a file of several pieces by its catalogue category, its girths over
    all its pieces). ``models``: the garments draped (an outfit's in the order given to ``drape_outfit``); the
    advice in layer order."""
    pairs = ([(r, models[i]) for r, i in zip(result.results, result.order)] if isinstance(result, OutfitResult)
             else [(result, models[0])])
    out = []
    for r, model in pairs:
        meta = model.meta
        advice = advise_size(meta.size or "", meta.id, meta.category, body, r.vertices, r.faces, model.vertices,
                             r.metrics, model.fabric.comfort_stretch)
        r.metrics["verdict"], r.metrics["verdict_reason"] = advice.verdict, advice.reason
        out.append(advice)
    return out


def simulate_motion(catalogue: Catalogue, request: TryOnRequest, on_frame: FrameCallback | None = None
                    ) -> CachedTryOn:
    """A motion (``request.poses``): the garment draped in the first pose, then carried to each next one and
    draped on from where it is (``sim.repose``). The first pose's result is the run's; ``extra["motion"]`` holds
    every pose's (result, body vertices (n, 3) m)."""
    if catalogue.get(request.garment_id) is None:
        raise KeyError(request.garment_id)
    settings = request.settings.to_settings()
    model = catalogue.model(request.garment_id, settings.simplification)
    if piece_categories(model) is not None:
        raise ValueError("a motion (poses) is not available for a garment file of several pieces (an outfit)")
    measurements = to_body_params(request.measurements)[0]
    motion, first_body = [], None
    d = None
    for pose in request.poses:
        body = build_body(measurements, Pose(**pose.angles()))
        d = start(body, model, settings) if d is None else repose(d, body)
        result, _ = settle(d, on_frame)
        if first_body is None:
            first_body = body
        else:
            d, result, _ = redrape_if_off(d, result, on_frame)
        motion.append((judged(result, body, [model]), body.vertices))
    run = CachedTryOn(result=motion[0][0], body=body_mesh(first_body), settings=settings)
    run.extra["motion"] = motion
    return run


def motion_glb(run: CachedTryOn, faces_body: np.ndarray) -> bytes:
    """A motion's animated GLB (``export.morph_glb``): the garment (vertex colours by its first pose's strain)
    and the body, one morph target per pose after the first, one second per pose."""
    motion = run.extra["motion"]
    first = motion[0][0]
    colours = strain_colours(first.strain, SimSettings().strain_limit[0])
    return morph_glb([("garment", [r.vertices for r, _ in motion], first.faces, colours),
                      ("body", [v for _, v in motion], faces_body, None)])


def prepare_outfit(catalogue: Catalogue, request: TryOnRequest) -> tuple[Body, list[GarmentModel], SimSettings]:
    """The body, the garment models (request order) and the settings of an outfit request. KeyError for a
    garment not in the catalogue."""
    for gid in request.ids:
        if catalogue.get(gid) is None:
            raise KeyError(gid)
    settings = request.settings.to_settings()
    measurements, pose = to_body_params(request.measurements, request.pose)
    return build_body(measurements, pose), outfit_models(catalogue, request, settings.simplification), settings


def result_json(result: TryOnResult | OutfitResult, cached_answer_s: float | None = None) -> dict:
    """The JSON answer (``TryOnOut``, or ``OutfitOut`` for an outfit): the fitted garment and the metrics with
    the per-vertex strain.

    cached_answer_s: for a result served from the cache, the seconds this answer took: it becomes
    ``wall_seconds`` (with ``cached: true``), and the run's own time ``simulation_wall_seconds``."""
    if isinstance(result, OutfitResult):
        return outfit_json(result, cached_answer_s)
    m = result.metrics
    metrics = {
        **run_metrics(m, cached_answer_s),
        "balanced": bool(m["balanced"]),
        "rest_speed_mm_s": None if m["rest_speed_mm_s"] is None else round(float(m["rest_speed_mm_s"]), 3),
        "unbalanced_force": None if m["unbalanced_force"] is None else round(float(m["unbalanced_force"]), 4),
        "penetrating_vertices": int(m["penetrating_vertices"]),
        "max_penetration_mm": round(float(m["max_penetration_mm"]), 3),
        "body_through_vertices": int(m["body_through_vertices"]),
        "max_body_through_mm": round(float(m["max_body_through_mm"]), 3),
        "max_strain": round(float(m["max_strain"]), 5),
        "strain": np.round(result.strain, 4).tolist(),
        "display_max_strain": round(float(m["display_max_strain"]), 5),
        "self_crossings": int(m["self_crossings"]),
        "strain_by_kind": m.get("strain_by_kind", {}),
        "too_tight": m.get("too_tight", {}),
        "openings_on_limbs": m.get("openings_on_limbs"),
        "limb_openings": m.get("limb_openings", []),
        "ends_cm": m.get("ends_cm", {}),
        "length": length_notes(m.get("ends_cm") or {}),
        "slid_cm": round(float(m["slid_cm"]), 1),
        "stays_up": bool(m["stays_up"]),
        "verdict": m.get("verdict"),
        "verdict_reason": m.get("verdict_reason"),
        "sized_to_body": bool(m.get("sized_to_body", False)),
        "pose": m.get("pose", {}),
        "motion_max_penetration_mm": (None if m.get("motion_max_penetration_mm") is None
                                      else round(float(m["motion_max_penetration_mm"]), 3)),
    }
    if "layer_penetrating_vertices" in m:  # a file of a top and a bottom, draped as layers
        metrics["layer_penetrating_vertices"] = int(m["layer_penetrating_vertices"])
        metrics["max_layer_penetration_mm"] = float(m["max_layer_penetration_mm"])
    return {"garment": mesh_json(result.vertices, result.faces), "metrics": metrics}


def run_metrics(m: dict, cached_answer_s: float | None) -> dict:
    """What every answer says of its run: steps, simulated and wall seconds (see ``result_json``), whether it
    came from the cache, whether it reached rest."""
    return {
        "steps": int(m["steps"]),
        "sim_seconds": float(m["sim_seconds"]),
        "wall_seconds": float(m["wall_seconds"]) if cached_answer_s is None else round(cached_answer_s, 4),
        "simulation_wall_seconds": float(m["wall_seconds"]),
        "cached": cached_answer_s is not None,
        "rest_reached": bool(m["rest_reached"]),
    }


def outfit_json(result: OutfitResult, cached_answer_s: float | None = None) -> dict:
    """An outfit's JSON answer (``OutfitOut``): each garment's mesh and metrics (as ``result_json``'s), in layer
    order, and the outfit's metrics."""
    m = result.metrics
    garments = []
    for layer, (gid, r) in enumerate(zip(m["layers"], result.results)):
        one = result_json(r, cached_answer_s)
        garments.append({"garment_id": gid, "layer": layer, **one["garment"], "metrics": one["metrics"]})
    metrics = {
        **run_metrics(m, cached_answer_s),
        "tuck": m["tuck"],
        "layers": list(m["layers"]),
        "penetrating_vertices": sum(int(r.metrics["penetrating_vertices"]) for r in result.results),
        "layer_penetrating_vertices": int(m["layer_penetrating_vertices"]),
        "max_layer_penetration_mm": float(m["max_layer_penetration_mm"]),
        "tuck_as_asked": m["tuck_as_asked"],
    }
    return {"garments": garments, "metrics": metrics}


def motion_json(run: CachedTryOn, cached_answer_s: float | None = None) -> dict:
    """A motion's JSON answer: the first pose's answer (``result_json``) and ``poses``: each pose's built pose
    and metrics, in order."""
    out = result_json(run.result, cached_answer_s)
    out["poses"] = [{"pose": r.metrics.get("pose", {}), "metrics": result_json(r, cached_answer_s)["metrics"]}
                    for r, _ in run.extra["motion"]]
    return out


def result_glb(result: TryOnResult | OutfitResult) -> bytes:
    """The fitted garment as GLB, vertex colours by strain; an outfit's garments each as a node of their own,
    named by catalogue id, innermost first."""
    limit = SimSettings().strain_limit[0]
    if isinstance(result, OutfitResult):
        return scene_bytes([(gid, r.vertices, r.faces, strain_colours(r.strain, limit))
                            for gid, r in zip(result.metrics["layers"], result.results)])
    return mesh_bytes(result.vertices, result.faces, "glb", strain_colours(result.strain, limit))


def strain_colours(strain: np.ndarray, limit: float) -> np.ndarray:
    """RGBA uint8 per vertex: blue (no strain) -> green -> red (at the structural limit or beyond)."""
    t = np.clip(np.asarray(strain, float) / max(limit, 1e-9), 0.0, 1.0)
    rgb = np.stack([np.clip(2 * t - 0.5, 0, 1), 1 - np.abs(2 * t - 1), np.clip(1 - 2 * t, 0, 1)], axis=1)
    return np.concatenate([(rgb * 255).astype(np.uint8), np.full((len(t), 1), 255, np.uint8)], axis=1)
