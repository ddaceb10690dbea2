"""Size advice in the service: a style's sizes draped on the simulation pool and kept in the result cache.

``style_advice`` is blocking (call it from a worker thread, not the event loop). Each size's drape is the
try-on ``POST /api/tryon`` would run for that garment with the same measurements and pose and the default
settings, under the same result-cache key (``pool.tryon_key``): a size already tried on is not simulated
again, and the page shows any size's drape afterwards without simulating. At most ``pool.workers`` of one
advice's drapes are admitted at once (more would only wait for a worker, taking waiting places other
shoppers' try-ons need); when the pool admits none of them, ``PoolFull`` (503 with Retry-After).
"""

from __future__ import annotations

from concurrent.futures import FIRST_COMPLETED, Future, wait

from tryon.api.pool import PoolFull, ResultCache, SimPool, tryon_key
from tryon.api.service import simulate
from tryon.api.schemas.bodies import to_body_params
from tryon.api.schemas.fit import FitRequest
from tryon.api.schemas.tryon import TryOnRequest
from tryon.body.build import build_body
from tryon.fit.advice import Drape, advise_style
from tryon.garment.catalogue import Catalogue
from tryon.garment.model import GarmentMeta


def style_advice(pool: SimPool, cache: ResultCache, catalogue: Catalogue, entries: list[GarmentMeta],
                 request: FitRequest) -> dict:
    """``FitOut`` (without ``wall_seconds``) for ``request`` over the style's ``entries`` (in size order).
    Raises PoolFull when the pool admits none of the drapes it needs."""

    def drape_sizes(indices: list[int]) -> dict[int, Drape | str]:
        out: dict[int, Drape | str] = {}
        pending = []
        for i in indices:
            tryon = TryOnRequest(garment_id=entries[i].id, measurements=request.measurements, pose=request.pose)
            key = tryon_key(tryon, catalogue)
            hit = cache.get(key)
            if hit is not None:
                out[i] = Drape(hit.result.vertices, hit.result.faces, hit.result.metrics, hit.extra.get("advice"))
            else:
                pending.append((i, tryon, key))
        in_flight: dict[Future, tuple] = {}
        while pending or in_flight:
            while pending and len(in_flight) < pool.workers:
                i, tryon, key = pending[0]
                guard = pool.guard()
                try:
                    future = pool.submit(simulate, catalogue, tryon, guard)
                except PoolFull:
                    if not in_flight:
                        raise
                    break  # the pool is full of other try-ons: wait for one of ours to finish
                pending.pop(0)
                in_flight[future] = (i, key, guard)
            done, _ = wait(list(in_flight), return_when=FIRST_COMPLETED)
            for future in done:
                i, key, guard = in_flight.pop(future)
                try:
                    run = future.result()
                except (KeyError, ValueError) as exc:
                    out[i] = f"not draped: this size could not be draped ({exc})"
                    continue
                if guard.stopped_by is not None:  # cut short: not kept, not judged
                    out[i] = "not draped: the drape ran past the service's time limit"
                    continue
                cache.put(key, run)
                out[i] = Drape(run.result.vertices, run.result.faces, run.result.metrics, run.extra.get("advice"))
        return out

    measurements, pose = to_body_params(request.measurements, request.pose)
    body = build_body(measurements, pose)
    advice, recommended, reason, notes = advise_style(entries, request.measurements.model_dump(), body, drape_sizes,
                                                      lambda gid: catalogue.model(gid).vertices, request.preference)
    return {"style": request.style, "preference": request.preference, "recommended": recommended, "reason": reason,
            "notes": notes, "sizes": [a.as_dict() for a in advice]}
