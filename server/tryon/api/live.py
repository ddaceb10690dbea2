"""One live try-on's simulation side (``WS /ws/tryon``): the request with its display fields, the init and
done messages, the run on a pool thread that hands frames to the event loop (``LiveSession``), and what a
cached try-on needs to be replayed. The route and the socket's coroutines are in ``routes/ws.py``."""

from __future__ import annotations

import asyncio
import json
import threading
import time
from collections import deque
from concurrent.futures import Future
from typing import Any, Literal

import numpy as np
from fastapi import HTTPException
from pydantic import BaseModel, ConfigDict, Field, model_validator

from tryon.api.export import json_bytes, mesh_arrays
from tryon.api.frames import BODY_VERTEX_LAYOUT, FLOAT32, FrameCodec, frame_due
from tryon.api.pool import CachedTryOn, RunGuard
from tryon.api.schemas.bodies import PoseIn, to_body_params
from tryon.api.schemas.tryon import TryOnRequest
from tryon.api.outfits import OutfitMesh, layered, outfit_models
from tryon.api.service import body_mesh, judged, prepare_outfit, prepare_tryon, result_json
from tryon.garment.catalogue import Catalogue
from tryon.garment.model import GarmentModel
from tryon.body.build import build_body
from tryon.body.params import Measurements, Pose
from tryon.sim.outfit import OutfitResult, drape_outfit, piece_categories
from tryon.sim.repose import PoseTransition, redrape_if_off, repose
from tryon.sim.run import TryOnResult, drape, settle
from tryon.sim.settings import SimSettings
from tryon.sim.start import start
from tryon.sim.state import Drape

# s: how long a re-pose's set-up waits for the sender to put the motion's step 0 on the wire (``post_start``)
# before it goes on. The set-up is Python-heavy and holds the GIL most of the time, and the event loop gets it
# back only every 5 ms switch interval: sent meanwhile, the body message and the frame reached the client ~40
# ms after they were handed over (the bench's client clock against the server's); waiting, the set-up starts
# a few ms later and they go at once. A bound, not a pause: it returns as soon as the frame is sent.
FIRST_FRAME_WAIT_S = 0.05


class LiveTryOnRequest(TryOnRequest):
    """``POST /api/tryon``'s body plus the frame rate the client wants, and whether the connection stays open
    for re-posing (``live``)."""

    fps: int = Field(30, ge=1, le=60, description="frames per second of wall time to send, 1/s; range [1, 60]")
    encoding: Literal["float32", "uint16"] = Field(
        "float32", description="frame positions: float32 metres, or uint16 quantized in a box around the "
                               "body (half the bytes, ~0.04 mm steps)")
    live: bool = Field(False, description="keep the connection open after done: the client may then send "
                                          "{\"type\": \"pose\", \"pose\": ...} at any time and the garment is "
                                          "carried to the new pose and draped on (one garment: garment_id)")

    @model_validator(mode="after")
    def _live_is_one_garment(self) -> "LiveTryOnRequest":
        if self.live and self.garment_ids is not None:
            raise ValueError("live re-posing takes one garment (garment_id), not an outfit (garment_ids)")
        if self.poses is not None:
            raise ValueError("poses (a motion) is for POST /api/tryon; over the stream send pose updates "
                             "(\"live\": true)")
        return self


class PoseUpdate(BaseModel):
    """A live session's pose update: ``{"type": "pose", "pose": "hands_on_hips"}`` or angles (degrees)."""

    model_config = ConfigDict(extra="forbid")

    type: Literal["pose"] = Field(description="the message type")
    pose: PoseIn = Field(description="pose angles, degrees, or a named pose (GET /api/bodies/ranges)")


def _entry(meta) -> dict:
    return {"id": meta.id, "name": meta.name, "category": meta.category, "size": meta.size,
            "vertices": meta.vertices, "faces": meta.faces, "coarse_vertices": meta.coarse_vertices}


def init_message(body: dict, model: GarmentModel | OutfitMesh, sim_settings: SimSettings) -> dict:
    """The init message without its ``encoding`` (see :func:`with_encoding`): topology, the body (its
    ``routes.tryon.body_mesh``), the garment's catalogue facts (an outfit's: each garment's, with its
    vertex and face ranges, innermost first), the run's settings."""
    out = {
        "type": "init",
        "vertex_count": int(len(model.vertices)),
        "face_count": int(len(model.faces)),
        "faces": np.ascontiguousarray(model.faces, dtype=np.int32),
        "body": {**mesh_arrays(body["vertices"], body["faces"]), "achieved": body["achieved"]},
        "max_steps": int(sim_settings.max_steps),
        "time_step": float(sim_settings.time_step),
        "strain_limit": float(sim_settings.strain_limit[0]),  # structural springs' stretch limit
    }
    if isinstance(model, OutfitMesh):
        out["garments"] = [{**_entry(m.meta), **r} for m, r in zip(model.models, model.ranges)]
    else:
        out["garment"] = _entry(model.meta)
    return out


def with_encoding(init_text: str, codec: FrameCodec, vertex_count: int) -> str:
    """The init JSON text (an object) with ``"encoding"`` added: the (large) rest is serialised once and
    kept, so a cached try-on can be replayed in any encoding without re-serialising two meshes."""
    return init_text[:-1] + ',"encoding":' + json.dumps(codec.describe(vertex_count), separators=(",", ":")) + "}"


def done_message(result: TryOnResult | OutfitResult, stopped_by: str | None,
                 cached_answer_s: float | None = None) -> dict:
    """The done message: the same metrics as ``POST /api/tryon``, the per-vertex strain beside them (an
    outfit's: its metrics with ``garments``, each garment's metrics, and every garment's strain one after the
    other). ``stopped_by``: the run's ``RunGuard.stopped_by``; ``cached_answer_s``: see ``result_json``."""
    answer = result_json(result, cached_answer_s)
    metrics = answer["metrics"]
    if isinstance(result, OutfitResult):
        metrics["garments"] = [{"garment_id": g["garment_id"], "layer": g["layer"], **g["metrics"]}
                               for g in answer["garments"]]
        strain = [s for g in metrics["garments"] for s in g.pop("strain")]
    else:
        strain = metrics.pop("strain")
    if stopped_by == "wall_limit":
        metrics["timed_out"] = True
    return {"type": "done", "metrics": metrics, "strain": strain, "stopped_by": stopped_by,
            "timed_out": stopped_by == "wall_limit", "cached": cached_answer_s is not None}


def shown_model(catalogue: Catalogue, request: TryOnRequest, run: CachedTryOn) -> GarmentModel | OutfitMesh:
    """What a cached try-on's frames show: its garment's model, or the outfit's models in layer order."""
    simplification = run.settings.simplification
    if request.outfit:
        return layered(outfit_models(catalogue, request, simplification), request.tuck)
    return catalogue.model(request.garment_id, simplification)


def replay_parts(run: CachedTryOn, model: GarmentModel | OutfitMesh) -> tuple[str, np.ndarray]:
    """The init message's text without its encoding and the body's bounding box (2, 3) m of a try-on
    (``model``: its garment), made once and kept with it in ``run.extra``: ~0.5 MB of JSON, made on a
    worker, never on the event loop. A try-on first asked for over REST gets them when a stream replays it."""
    if "init_base" not in run.extra:
        vertices = run.body["vertices"]
        run.extra["body_box"] = np.stack([vertices.min(axis=0), vertices.max(axis=0)])
        run.extra["init_base"] = json_bytes(init_message(run.body, model, run.settings)).decode()
    return run.extra["init_base"], run.extra["body_box"]


def run_live(catalogue: Catalogue, request: LiveTryOnRequest, session: LiveSession,
             guard: RunGuard) -> tuple[CachedTryOn, dict] | None:
    """On a worker: build the body, load the garment, hand over init, drape. Returns (the run as the
    result cache keeps it, the done message), or None when the client left before a worker was free."""
    guard.start()
    if guard.cancelled.is_set():
        return None
    if request.outfit:
        body, models, sim_settings = prepare_outfit(catalogue, request)
        shown = layered(models, request.tuck)
    else:
        body, shown, sim_settings = prepare_tryon(catalogue, request)
    run = CachedTryOn(result=None, body=body_mesh(body), settings=sim_settings)
    # serialised here, on the worker: the init message carries two meshes (~0.5 MB of JSON), too much
    # work for the event loop
    init_base, box = replay_parts(run, shown)
    session.offer_init(init_base, shown, FrameCodec.around(request.encoding, box))
    if request.outfit:
        run.result = judged(drape_outfit(body, models, sim_settings, request.tuck, on_frame=guard), body, models)
    elif request.live:
        if piece_categories(shown) is not None:
            raise ValueError("live re-posing is not available for a garment file of several pieces (an outfit): "
                             "ask without \"live\" to drape it once in a pose")
        d = start(body, shown, sim_settings)
        run.result = judged(settle(d, guard)[0], body, [shown])
        session.reposing = LiveReposing(session, to_body_params(request.measurements)[0], d)
    else:
        run.result = judged(drape(body, shown, sim_settings, guard), body, [shown])
    return run, done_message(run.result, guard.stopped_by)


class LiveReposing:
    """A live session's re-posing (``"live": true``): the drape at rest (or given way) on the last pose's body,
    the measurements its bodies are built from, and the latest pose update waiting (latest wins: one slot).

    ``repose_to`` runs on a pool thread: it builds the new pose's body and plans the motion to it
    (``repose.PoseTransition``), sends the body (a ``body`` message, before the frames of that pose) and at once
    the motion's first frame (step 0: the garment where it is, the body still in the old pose), then sets the
    drape up, carries the garment to the new pose (``sim.repose``) and settles it, each frame with the body's
    part motions while the body moves (a ``body_pose`` message before the frame); it gives way to a newer pose
    once the body has reached its own (no done for that one)."""

    def __init__(self, session: "LiveSession", measurements: Measurements, drape: Drape):
        self.session = session
        self.measurements = measurements
        self.drape = drape
        self.settles = 0  # re-poses started

    def repose_to(self, update: int, pose: Pose, received_at: float, guard: RunGuard) -> dict | None:
        """Re-pose the drape to ``pose`` (update number ``update``, arrived at ``received_at``, monotonic s) and
        settle it; the done message, or None if a newer pose came first (``session.pending``)."""
        guard.start()
        session = self.session
        session.update_received_at = received_at
        session.update_first_frame_at = session.update_first_step_at = None
        body = build_body(self.measurements, pose)
        transition = PoseTransition(self.drape.control.body, body, garment=self.drape.state.x)
        vertices = FLOAT32.encode(body.vertices)  # binary: 12 bytes a vertex, 2.4 x less than JSON, no parse
        message = {"type": "body", "update": update, "pose": body.pose, "vertex_part": body.vertex_part,
                   "transition_steps": int(transition.steps), "vertices": {"binary_bytes": len(vertices),
                                                                          "layout": BODY_VERTEX_LAYOUT}}
        session.post_body(json_bytes(message).decode(), vertices)
        # the motion's step 0 right away, before the drape is set up (its collider, maps, springs: ~30 ms)
        session.post_start(self.drape.state.x, transition.start_motion())
        d = repose(self.drape, body, transition)
        self.settles += 1
        session.moving = d
        try:
            result, gave_way = settle(d, guard, give_way=lambda: session.pending is not None)
        finally:
            session.moving = None
            if d.state.step > d.control.startup:  # the garment is on the new body's pose: the next re-pose starts here
                self.drape = d
        if gave_way:
            return None
        d, result, redraped = redrape_if_off(d, result, guard)
        result = judged(result, body, [d.model.garment])
        self.drape = d
        session.post_final(d.state.step, result.vertices)
        done = {**done_message(result, guard.stopped_by), "update": update, "redraped": redraped}
        first, stepped = session.update_first_frame_at, session.update_first_step_at
        done["metrics"]["wall_seconds"] = round(time.monotonic() - received_at, 4)
        done["time_to_first_frame_s"] = None if first is None else round(first - received_at, 4)
        done["time_to_first_step_s"] = None if stepped is None else round(stepped - received_at, 4)
        done["transition_steps"] = int(d.control.arms.steps)
        return done


def resume_live(session: "LiveSession", request: LiveTryOnRequest, model: GarmentModel, cached: CachedTryOn,
                codec: FrameCodec) -> None:
    """A live session from a cached try-on (blocking: a thread): its body built again and a drape at rest in the
    cached final state (``start`` from the coarse positions), for the pose updates to start from."""
    measurements, pose = to_body_params(request.measurements, request.pose)
    body = build_body(measurements, pose)
    d = start(body, model, cached.settings, initial=cached.result.coarse)
    session.codec, session._model = codec, model
    session.reposing = LiveReposing(session, measurements, d)


def _body_pose(moves: np.ndarray | None, step: int) -> str:
    """The ``body_pose`` message of a frame: each part's rigid motion ``moves`` (P, 4, 4) from the body message's
    pose (rows of R (3, 3) then t (3,), metres), or the body in that pose (None)."""
    if moves is None:
        return '{"type":"body_pose","parts":null}'
    parts = np.concatenate([moves[:, :3, :3].reshape(-1, 9), moves[:, :3, 3]], axis=1)
    return json.dumps({"type": "body_pose", "step": int(step), "parts": np.round(parts, 6).tolist()},
                      separators=(",", ":"))


def failure_reason(error: BaseException, request: TryOnRequest) -> str:
    """A failed try-on in words."""
    if isinstance(error, HTTPException):
        return str(error.detail)
    if isinstance(error, KeyError):
        return f"no garment with id {error.args[0]!r} in the catalogue (see GET /api/garments)"
    if isinstance(error, ValueError):
        return f"cannot run this try-on: {error}"
    return f"the simulation failed ({type(error).__name__}: {error})"


class LiveSession:
    """The state shared by one connection's simulation thread and its sender coroutine.

    The thread hands things over through ``call_soon_threadsafe`` only; the loop owns the fields.
    The latest-frame slot holds ``(step, positions bytes)``; the sender numbers the frames it sends.
    """

    def __init__(self, loop: asyncio.AbstractEventLoop, fps: int):
        self.loop = loop
        self.interval_s = 1.0 / fps
        self.cancelled = threading.Event()  # read by the simulation thread's RunGuard
        self.wake = asyncio.Event()
        self.init: str | None = None  # the init message, as JSON text
        self.latest: tuple[int, bytes] | None = None  # the latest-frame slot
        self.finished = False
        self.frames_sent = 0
        self.frames_offered = 0
        self.bytes_sent = 0
        self.first_frame_at: float | None = None
        self.started_at = time.monotonic()
        self.future: Future | None = None  # the pool job
        # simulation-thread side
        self._next_offer_at = 0.0
        self._model: Any = None
        self.codec = FLOAT32  # set with the init message, before any frame
        # live re-posing (``"live": true``): after the first done, texts and frames go out in order through
        # the outbox (a frame replaces a frame still waiting at its end); the pose slot holds the latest update
        self.reposing: LiveReposing | None = None  # set by the first drape's worker
        self.live = False
        # ("text", str) | ("bytes", a body message's vertices) | ("frame", step, payload, body motion text | None)
        self.outbox: deque = deque()
        self.pending: tuple[int, Any, float] | None = None  # (update number, Pose, monotonic s received)
        self.updates = 0
        self.pose_arrived = asyncio.Event()
        self.moving: Drape | None = None  # sim thread: the re-posed drape while it settles
        self.frame_sent = threading.Event()  # set by the live sender after each frame it sends
        self.update_received_at = 0.0
        self.update_first_frame_at: float | None = None  # the update's first frame (its step 0)
        self.update_first_step_at: float | None = None  # its first simulated step's frame

    # -- called on the simulation thread ---------------------------------------------------------
    def offer_init(self, init_base: str, model: Any, codec: FrameCodec) -> None:
        """The init message (JSON text without ``encoding``), the model whose frames follow, their codec."""
        self.codec = codec
        self._model = model
        self.loop.call_soon_threadsafe(self._set_init, with_encoding(init_base, codec, len(model.vertices)))

    def on_frame(self, step: int, coarse: np.ndarray) -> bool:
        """Hand a frame over when one is due (at most ``fps`` per second); never blocks. Only these
        frames are expanded to the full mesh."""
        now = time.monotonic()
        if now < self._next_offer_at or self._model is None:
            return True
        # a fixed cadence (not "now + interval"): steps rarely land on the deadline, and waiting a full
        # interval from a late step would deliver well under fps; the sender keeps the same cadence
        self._next_offer_at = frame_due(self._next_offer_at, now, self.interval_s)
        payload = self.codec.encode(self._model.expand(coarse))
        if self.live:
            if self.update_first_frame_at is None:
                self.update_first_frame_at = now
            if self.update_first_step_at is None:
                self.update_first_step_at = now
            self.loop.call_soon_threadsafe(self._put_live_frame, (step, payload, self._motion_text()))
        else:
            self.loop.call_soon_threadsafe(self._put_frame, (step, payload))
        return True

    def _motion_text(self) -> str | None:
        """The ``body_pose`` message of the body the frame's garment is on, while a re-posed drape settles:
        each part's rigid motion from the new body's own pose (rows of R (3, 3) then t (3,), metres), the
        identity once the body has reached it."""
        d = self.moving
        if d is None:
            return None
        return _body_pose(d.control.arms.current() if d.state.step <= d.control.arms.steps else None, d.state.step)

    def post_start(self, x: np.ndarray, moves: np.ndarray | None) -> None:
        """A re-pose's step 0 for the live outbox (sim thread), before its drape is set up: the garment's coarse
        points x (k, 3) m where they are, the body posed by ``moves`` (P, 4, 4) from its new pose (None: in
        it)."""
        self.update_first_frame_at = time.monotonic()
        payload = self.codec.encode(self._model.expand(x))
        self.frame_sent.clear()
        self.loop.call_soon_threadsafe(self._put_live_frame, (0, payload, _body_pose(moves, 0)))
        self.frame_sent.wait(FIRST_FRAME_WAIT_S)

    def post_text(self, text: str) -> None:
        """A text message for the live outbox, after everything handed over before it (any thread)."""
        self.loop.call_soon_threadsafe(self._put_text, text)

    def post_body(self, text: str, vertices: bytes) -> None:
        """A body message for the live outbox (sim thread): its JSON text, then its vertices as the binary
        message right after it (``BODY_VERTEX_LAYOUT``), nothing between the two."""
        self.loop.call_soon_threadsafe(self._put_body, text, vertices)

    def post_final(self, step: int, vertices: np.ndarray) -> None:
        """A settle's final state for the live outbox (sim thread): the body in its own pose."""
        self.loop.call_soon_threadsafe(self._put_live_frame,
                                       (step, self.codec.encode(vertices), '{"type":"body_pose","parts":null}'))

    # -- called on the event loop ------------------------------------------------------------------
    def _set_init(self, message: str) -> None:
        self.init = message
        self.wake.set()

    def _put_frame(self, frame: tuple[int, bytes]) -> None:
        self.latest = frame  # replaces an unsent frame: a slow client never gets a backlog
        self.frames_offered += 1
        self.wake.set()

    def _put_text(self, text: str) -> None:
        self.outbox.append(("text", text))
        self.wake.set()

    def _put_body(self, text: str, vertices: bytes) -> None:
        self.outbox.append(("text", text))
        self.outbox.append(("bytes", vertices))
        self.wake.set()

    def _put_live_frame(self, frame: tuple) -> None:
        if self.outbox and self.outbox[-1][0] == "frame":
            self.outbox.pop()  # a frame not sent yet: the newer one replaces it (no backlog)
        self.outbox.append(("frame", *frame))
        self.frames_offered += 1
        self.wake.set()

    def offer_pose(self, pose: Any) -> None:
        """A pose update arrived (event loop): it replaces any update still waiting (latest wins)."""
        self.updates += 1
        self.pending = (self.updates, pose, time.monotonic())
        self.pose_arrived.set()

    def take_pose(self) -> tuple[int, Any, float] | None:
        out, self.pending = self.pending, None
        return out

    def finish(self, step: int, vertices: np.ndarray) -> None:
        """The final state: always sent, replacing any frame still waiting."""
        self._put_frame((step, self.codec.encode(vertices)))
        self.finished = True

    def stop(self) -> None:
        """The client is gone (or the run failed): stop simulating, free a waiting slot at once."""
        if self.future is not None:
            self.future.cancel()  # only succeeds while the job still waits for a worker
        self.cancelled.set()
        self.finished = True
        self.wake.set()
        self.pose_arrived.set()
