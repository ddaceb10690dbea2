"""Warm-up: compile (or load from numba's disk cache) every kernel a request needs, before the service
says it is ready.

Numba compiles a kernel on its first call. On a fresh machine that made the first ``POST /api/bodies``
take ~11 s and the first try-on ~16-20 s, while ``/api/health`` already said ok. :func:`warm_up` runs the
same code paths on a tiny scene instead: it ingests two small generated garments (a T-shirt and a pair of
trousers, so the garment preparation, a top's and a bottom's drape and the legs' code all run) into a
throw-away catalogue, builds a body, drapes each garment to rest through the API's own ``run_tryon``, and
encodes the answers (JSON, GLB). Cold it takes ~35-40 s on one core here; with the
kernels cached on disk ~1-2 s. It runs once per process: later calls return at once.

:class:`WarmUp` runs it on a background thread of the service; ``/api/health`` answers 503
``"starting"`` until it has finished (see ``routes/health.py``).
"""

from __future__ import annotations

import logging
import tempfile
import threading
import time
from pathlib import Path

log = logging.getLogger(__name__)

# The generated garments warmed with (tryon.garment.generate kinds and the category each is draped as):
# a top and a bottom with legs reach every kernel a catalogue try-on calls (a skirt's and a dress's drape
# call no kernel these two do not).
WARM_GARMENTS = (("tshirt", "top"), ("trousers", "bottom"))
# The body warmed on: the API's default-sized medium body (cm).
WARM_MEASUREMENTS = {"height": 170.0, "chest": 92.0, "waist": 76.0, "hips": 98.0}

_lock = threading.Lock()
_done_seconds: float | None = None  # set once this process has warmed up


def warm_up() -> float:
    """Run every stage a request runs, once per process (see the module docstring). Returns the seconds
    this call spent (0.0 when the process was already warm). Blocking; thread-safe."""
    global _done_seconds
    with _lock:
        if _done_seconds is not None:
            return 0.0
        started = time.perf_counter()
        _exercise()
        _done_seconds = time.perf_counter() - started
        log.info("kernels ready in %.1f s", _done_seconds)
        return _done_seconds


def _exercise() -> None:
    # imported here: ``tryon.api.routes`` imports this module's users, and the heavy imports are part of
    # what the warm-up warms
    from tryon.api.export import json_bytes, mesh_bytes
    from tryon.api.routes.bodies import body_glb, body_json
    from tryon.api.service import result_glb, result_json, run_tryon, strain_colours
    from tryon.api.schemas.bodies import to_body_params
    from tryon.api.schemas.tryon import TryOnRequest
    from tryon.body.build import build_body
    from tryon.garment.catalogue import Catalogue
    from tryon.garment.generate import garment_mesh, obj_text

    request = TryOnRequest(garment_id="-", measurements=WARM_MEASUREMENTS)
    body = build_body(*to_body_params(request.measurements, request.pose))  # POST /api/bodies
    json_bytes(body_json(body, request.pose.angles()))
    body_glb(body)
    with tempfile.TemporaryDirectory(prefix="tryon-warmup-") as tmp:
        catalogue = Catalogue(Path(tmp) / "data")
        ids = []
        for kind, category in WARM_GARMENTS:
            path = Path(tmp) / f"{kind}.obj"
            path.write_text(obj_text(garment_mesh(kind, "S"), kind))
            entry = catalogue.ingest(path, name=kind, category=category, size="S", units="m")
            ids.append(entry.id)
            result = run_tryon(catalogue, request.model_copy(update={"garment_id": entry.id}))
            result_json(result)
            mesh_bytes(result.vertices, result.faces, "glb", strain_colours(result.strain, 0.1))
            if category == "top":  # a live session's re-pose (WS "live": true): carried to a new pose, settled
                _repose(body, catalogue.model(entry.id))
        # an outfit, tucked in and out (the layers' kernels, the outfit's answers)
        for tuck in ("out", "in"):
            outfit = run_tryon(catalogue, request.model_copy(update={"garment_id": None, "garment_ids": ids,
                                                                     "tuck": tuck}))
            result_json(outfit)
            result_glb(outfit)


def _repose(body, model) -> None:
    """A drape of ``model`` on ``body`` re-posed as a live session does (``api.live.LiveReposing``): to an
    asymmetric pose with a hand turned at the wrist (every body kernel's posed path), settled to rest."""
    from tryon.api.pool import RunGuard
    from tryon.body.build import build_body
    from tryon.body.params import Measurements, Pose, pose_from
    from tryon.sim.repose import repose
    from tryon.sim.run import settle
    from tryon.sim.start import start

    d = start(body, model)
    settle(d, RunGuard(60.0))
    measurements = Measurements(**WARM_MEASUREMENTS)
    for pose in (pose_from("hands_on_hips"), Pose(arm_angle_left=70.0, arm_forward_right=40.0, leg_spread_left=12.0)):
        d = repose(d, build_body(measurements, pose))
        settle(d, RunGuard(60.0), give_way=lambda: False)


class WarmUp:
    """The service's warm-up, on a daemon thread started by :meth:`start`.

    ``state``: ``"starting"`` until it has run, then ``"ready"``; ``"failed"`` if it raised (the service
    still serves: kernels then compile on first use, and the error is logged and shown by health)."""

    def __init__(self) -> None:
        self.state = "starting"
        self.seconds: float | None = None
        self.error: str | None = None
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        if self._thread is not None:
            return
        if _done_seconds is not None:  # this process is already warm (tests create many apps)
            self.state, self.seconds = "ready", 0.0
            return
        self._thread = threading.Thread(target=self._run, name="tryon-warmup", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        started = time.perf_counter()
        try:
            warm_up()
            self.state = "ready"
        except Exception as exc:  # noqa: BLE001 - a failed warm-up must not stop the service
            log.exception("warm-up failed; kernels will compile on first use")
            self.error = f"{type(exc).__name__}"
            self.state = "failed"
        self.seconds = round(time.perf_counter() - started, 2)

    @property
    def ready(self) -> bool:
        return self.state != "starting"

    def stats(self) -> dict:
        out = {"state": self.state, "seconds": self.seconds}
        if self.error:
            out["error"] = self.error
        return out
