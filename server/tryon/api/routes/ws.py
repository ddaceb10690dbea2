"""``WS /ws/tryon``: a live try-on, streamed while the garment drapes (SPEC section 6).

Protocol (one try-on per connection):

1. the client sends one JSON text message: the same body as ``POST /api/tryon`` plus an optional
   ``fps`` (frames per second of wall time it wants, 1-60, default 30) and ``encoding`` (float32 |
   uint16, default float32);
2. the server answers one JSON ``{"type": "init", ...}``: the garment's full-mesh ``faces`` and
   ``vertex_count``, the ``body`` mesh, the garment's catalogue entry and the frame ``encoding``;
3. then binary frames, each the FULL mesh's vertex positions: a 12-byte header (little-endian uint32
   frame number, counting 0, 1, 2, ... over the frames sent; uint32 simulation step; float32 seconds
   since the request was accepted) followed by ``vertex_count * 3`` little-endian float32 x, y, z in
   metres (``12 + 12 * vertex_count`` bytes). The last frame is the final state. With
   ``"encoding": "uint16"`` in the request the positions are uint16 q instead, position = origin + q *
   scale (metres, per axis; origin and scale in the init message's ``encoding``): half the bytes;
4. then one JSON ``{"type": "done", "metrics": {...}, "strain": [...], "cached": bool, ...}`` and a
   normal close (1000).

Any failure (not JSON, a bad field, an unknown garment, a failed simulation) is one JSON
``{"type": "error", "reason": "..."}`` followed by a normal close. A full server sends the error and
closes with 1013 (try again later).

Flow control: the simulation runs on a pool thread; its ``on_frame`` hands at most ``fps`` frames per
second to the event loop (``loop.call_soon_threadsafe``) into a latest-frame slot, expanding coarse ->
full only for those. The sender coroutine sends the slot's content when the socket is free, so a slow
client gets fewer frames instead of a queue (intermediate frames are dropped, the final one always goes
out), and no two frames leave less than 1 / fps apart. When the client goes away the run stops at its
next step; a job still waiting for a worker is skipped.

A request equal to an earlier finished one, over this socket or ``POST /api/tryon`` (garment, measurements,
pose, settings; see ``tryon.api.pool.request_key``), is served from the one result cache: init, the final
frame, done with ``"cached": true`` (and ``metrics.wall_seconds`` the time of this answer).
"""

from __future__ import annotations

import asyncio
import json
import logging
import struct
import threading
import time
from concurrent.futures import CancelledError as FutureCancelled
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from fastapi import APIRouter, HTTPException, WebSocket, WebSocketDisconnect
from pydantic import Field, ValidationError
from starlette.websockets import WebSocketState

from tryon.api.deps import get_catalogue
from tryon.api.export import json_bytes, mesh_arrays
from tryon.api.pool import CachedTryOn, PoolFull, RunCancelled, RunGuard, get_pool, get_result_cache, tryon_key
from tryon.api.routes.tryon import body_mesh, prepare_tryon, result_json
from tryon.api.schemas.tryon import TryOnRequest
from tryon.garment.catalogue import Catalogue
from tryon.garment.model import GarmentModel
from tryon.sim.run import TryOnResult, drape
from tryon.sim.settings import SimSettings

router = APIRouter(tags=["ws"])
log = logging.getLogger(__name__)

FRAME_HEADER = struct.Struct("<IIf")  # frame number, simulation step, seconds since the request
CLOSE_NORMAL = 1000
CLOSE_TRY_AGAIN_LATER = 1013  # RFC 6455 registry: "Try Again Later"
# bytes: a close frame is a control frame (at most 125 bytes of payload), 2 of them the close code
MAX_CLOSE_REASON_BYTES = 123
# Seconds to wait for the client's request before giving up on the connection.
REQUEST_TIMEOUT_S = 30.0


# m: how far beyond the body's bounding box quantized (uint16) positions reach; a garment hanging or
# sliding further is clamped to the box. 65,535 levels over a 1.8 m body + 2 x 0.25 m: 0.035 mm.
QUANT_MARGIN = 0.25


@dataclass(frozen=True)
class FrameCodec:
    """How vertex positions are written in a frame.

    ``float32``: x, y, z little-endian float32, metres (12 bytes per vertex).
    ``uint16``: x, y, z little-endian uint16 q, with position = origin + q * scale per axis (metres;
    6 bytes per vertex, resolution ``scale`` ~0.04 mm); positions outside the box are clamped to it.
    """

    type: str = "float32"
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)

    @classmethod
    def around(cls, type_: str, vertices: np.ndarray) -> "FrameCodec":
        """The codec ``type_``; for uint16 its box is ``vertices``' bounding box grown by QUANT_MARGIN."""
        if type_ == "float32":
            return cls()
        lo = vertices.min(axis=0) - QUANT_MARGIN
        hi = vertices.max(axis=0) + QUANT_MARGIN
        return cls("uint16", tuple(float(v) for v in lo), tuple(float(v) for v in (hi - lo) / 65535.0))

    @property
    def bytes_per_vertex(self) -> int:
        return 12 if self.type == "float32" else 6

    def encode(self, vertices: np.ndarray) -> bytes:
        """(n, 3) metres -> the frame's position bytes."""
        if self.type == "float32":
            return np.ascontiguousarray(vertices, dtype="<f4").tobytes()
        q = np.rint((vertices - np.asarray(self.origin)) / np.asarray(self.scale))
        return np.clip(q, 0, 65535).astype("<u2").tobytes()

    def decode(self, data: bytes) -> np.ndarray:
        """Inverse of :meth:`encode` (tests, Python clients): (n, 3) float64 metres."""
        if self.type == "float32":
            return np.frombuffer(data, dtype="<f4").reshape(-1, 3).astype(np.float64)
        q = np.frombuffer(data, dtype="<u2").reshape(-1, 3)
        return np.asarray(self.origin) + q * np.asarray(self.scale)

    def describe(self, vertex_count: int) -> dict:
        """The init message's ``encoding``."""
        out = {
            "type": self.type,
            "byte_order": "little",
            "header_bytes": FRAME_HEADER.size,
            "header": ["frame:uint32", "step:uint32", "time_s:float32"],
            "layout": "xyz per vertex, metres" if self.type == "float32"
                      else "xyz per vertex: position = origin + q * scale, metres",
            "components": 3,
            "bytes_per_frame": FRAME_HEADER.size + self.bytes_per_vertex * vertex_count,
        }
        if self.type == "uint16":
            out.update(origin=list(self.origin), scale=list(self.scale))
        return out


FLOAT32 = FrameCodec()


def encoding(vertex_count: int, codec: FrameCodec = FLOAT32) -> dict:
    """How a binary frame is laid out; sent in the init message."""
    return codec.describe(vertex_count)


def encode_positions(vertices: np.ndarray, codec: FrameCodec = FLOAT32) -> bytes:
    """(n, 3) positions as the codec's bytes (default little-endian float32 x, y, z per vertex)."""
    return codec.encode(vertices)


def encode_frame(frame: int, step: int, vertices: np.ndarray | bytes, time_s: float = 0.0,
                 codec: FrameCodec = FLOAT32) -> bytes:
    """One binary frame: header (frame number, step, seconds since the request) + positions."""
    payload = vertices if isinstance(vertices, bytes) else codec.encode(vertices)
    return FRAME_HEADER.pack(frame, max(int(step), 0), time_s) + payload


def validation_reason(error: ValidationError) -> str:
    """A pydantic error in words, naming each bad field."""
    parts = []
    for e in error.errors():
        where = ".".join(str(x) for x in e.get("loc", ())) or "request"
        parts.append(f"{where}: {e.get('msg', 'invalid')}")
    return "invalid request: " + "; ".join(parts)


# -- the simulation side (runs on a pool thread) --------------------------------------------------------
class LiveTryOnRequest(TryOnRequest):
    """``POST /api/tryon``'s body plus the frame rate the client wants."""

    fps: int = Field(30, ge=1, le=60, description="frames per second of wall time to send, 1/s; range [1, 60]")
    encoding: Literal["float32", "uint16"] = Field(
        "float32", description="frame positions: float32 metres, or uint16 quantized in a box around the "
                               "body (half the bytes, ~0.04 mm steps)")


def init_message(body: dict, model: GarmentModel, sim_settings: SimSettings) -> dict:
    """The init message without its ``encoding`` (see :func:`with_encoding`): topology, the body (its
    ``routes.tryon.body_mesh``), the garment's catalogue facts, the run's settings."""
    meta = model.meta
    return {
        "type": "init",
        "vertex_count": int(len(model.vertices)),
        "face_count": int(len(model.faces)),
        "faces": np.ascontiguousarray(model.faces, dtype=np.int32),
        "body": {**mesh_arrays(body["vertices"], body["faces"]), "achieved": body["achieved"]},
        "garment": {"id": meta.id, "name": meta.name, "category": meta.category, "size": meta.size,
                    "vertices": meta.vertices, "faces": meta.faces, "coarse_vertices": meta.coarse_vertices},
        "max_steps": int(sim_settings.max_steps),
        "time_step": float(sim_settings.time_step),
        "strain_limit": float(sim_settings.strain_limit[0]),  # structural springs' stretch limit
    }


def with_encoding(init_text: str, codec: FrameCodec, vertex_count: int) -> str:
    """The init JSON text (an object) with ``"encoding"`` added: the (large) rest is serialised once and
    kept, so a cached try-on can be replayed in any encoding without re-serialising two meshes."""
    return init_text[:-1] + ',"encoding":' + json.dumps(codec.describe(vertex_count), separators=(",", ":")) + "}"


def done_message(result: TryOnResult, stopped_by: str | None, cached_answer_s: float | None = None) -> dict:
    """The done message: the same metrics as ``POST /api/tryon``, the per-vertex strain beside them.
    ``stopped_by``: the run's ``RunGuard.stopped_by``; ``cached_answer_s``: see ``result_json``."""
    metrics = result_json(result, cached_answer_s)["metrics"]
    strain = metrics.pop("strain")
    if stopped_by == "wall_limit":
        metrics["timed_out"] = True
    return {"type": "done", "metrics": metrics, "strain": strain, "stopped_by": stopped_by,
            "timed_out": stopped_by == "wall_limit", "cached": cached_answer_s is not None}


def replay_parts(run: CachedTryOn, model: GarmentModel) -> tuple[str, np.ndarray]:
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
    body, model, sim_settings = prepare_tryon(catalogue, request)
    run = CachedTryOn(result=None, body=body_mesh(body), settings=sim_settings)
    # serialised here, on the worker: the init message carries two meshes (~0.5 MB of JSON), too much
    # work for the event loop
    init_base, box = replay_parts(run, model)
    session.offer_init(init_base, model, FrameCodec.around(request.encoding, box))
    run.result = drape(body, model, sim_settings, guard)
    return run, done_message(run.result, guard.stopped_by)


def failure_reason(error: BaseException, request: TryOnRequest) -> str:
    """A failed try-on in words."""
    if isinstance(error, HTTPException):
        return str(error.detail)
    if isinstance(error, KeyError):
        return f"no garment with id {request.garment_id!r} in the catalogue (see GET /api/garments)"
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
        # interval from a late step would deliver well under fps; the sender still spaces frames 1/fps apart
        self._next_offer_at = max(self._next_offer_at + self.interval_s, now - self.interval_s)
        payload = self.codec.encode(self._model.expand(coarse))
        self.loop.call_soon_threadsafe(self._put_frame, (step, payload))
        return True

    # -- called on the event loop ------------------------------------------------------------------
    def _set_init(self, message: str) -> None:
        self.init = message
        self.wake.set()

    def _put_frame(self, frame: tuple[int, bytes]) -> None:
        self.latest = frame  # replaces an unsent frame: a slow client never gets a backlog
        self.frames_offered += 1
        self.wake.set()

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


async def _sender(ws: WebSocket, session: LiveSession) -> None:
    """Send init, then the latest frame whenever one is due (1 / fps after the last one) and the socket
    is free, until finished."""
    init_sent = False
    last_sent = -1e9
    try:
        while True:
            await session.wake.wait()
            session.wake.clear()
            if session.cancelled.is_set():
                return
            if not init_sent and session.init is not None:
                await ws.send_text(session.init)
                init_sent = True
            if init_sent and session.latest is not None:
                due = last_sent + session.interval_s
                # a loop, not one sleep: uvloop's timers count from the loop's cached time, which may be a
                # millisecond or more behind the clock under load, so a sleep can end that much early
                while (wait := due - time.monotonic()) > 0:
                    await asyncio.sleep(wait)  # a newer frame may replace this one meanwhile
                    if session.cancelled.is_set():
                        return
                (step, payload), session.latest = session.latest, None
                now = time.monotonic()
                data = encode_frame(session.frames_sent, step, payload, now - session.started_at)
                await ws.send_bytes(data)
                last_sent = now
                if session.first_frame_at is None:
                    session.first_frame_at = now
                session.frames_sent += 1
                session.bytes_sent += len(data)
            if session.finished and session.latest is None:
                return
    except (WebSocketDisconnect, RuntimeError, OSError):
        session.stop()


async def _watch_disconnect(ws: WebSocket, session: LiveSession) -> None:
    """Read until the client goes away, then stop the simulation (messages after the request are ignored)."""
    try:
        while True:
            message = await ws.receive()
            if message["type"] == "websocket.disconnect":
                break
    except (WebSocketDisconnect, RuntimeError, OSError):
        pass
    session.stop()


def close_reason(reason: str) -> str:
    """``reason`` cut to what a close frame can carry (RFC 6455: 123 bytes of UTF-8; a longer one makes
    the server drop the connection without a close frame), never in the middle of a character."""
    data = reason.encode("utf-8")
    if len(data) <= MAX_CLOSE_REASON_BYTES:
        return reason
    return data[:MAX_CLOSE_REASON_BYTES - 3].decode("utf-8", errors="ignore") + "..."


async def _send_error(ws: WebSocket, reason: str, code: int = CLOSE_NORMAL) -> None:
    """One JSON error message (the whole reason), then close with ``code`` and the reason cut to fit a
    close frame (quietly if the client is already gone)."""
    try:
        await ws.send_text(json.dumps({"type": "error", "reason": reason}))
        await ws.close(code=code, reason=close_reason(reason))
    except (WebSocketDisconnect, RuntimeError, OSError):
        pass


async def _close(ws: WebSocket) -> None:
    if ws.client_state == WebSocketState.CONNECTED:
        try:
            await ws.close(code=CLOSE_NORMAL)
        except (WebSocketDisconnect, RuntimeError, OSError):
            pass


async def _replay(ws: WebSocket, cached: CachedTryOn, request: LiveTryOnRequest, catalogue: Catalogue) -> None:
    """Serve a cached try-on (asked for before over REST or this socket) in the requested encoding: init,
    the final frame, done with ``cached: true``."""
    started = time.perf_counter()
    result = cached.result
    init_base, box = await asyncio.to_thread(
        lambda: replay_parts(cached, catalogue.model(request.garment_id, cached.settings.simplification)))
    codec = FrameCodec.around(request.encoding, box)
    await ws.send_text(with_encoding(init_base, codec, len(result.vertices)))
    frame = encode_frame(0, result.metrics.get("steps", 0), result.vertices, codec=codec)
    await ws.send_bytes(frame)
    done = {**done_message(result, None, time.perf_counter() - started), "frames_sent": 1, "bytes_sent": len(frame)}
    await ws.send_text(json.dumps(done, separators=(",", ":")))
    await ws.close(code=CLOSE_NORMAL)


@router.websocket("/ws/tryon")
async def tryon_ws(ws: WebSocket) -> None:
    """One live try-on; see the module docstring for the protocol."""
    await ws.accept()
    try:
        await _serve(ws)
    except (WebSocketDisconnect, asyncio.CancelledError):
        raise
    except Exception as e:  # a bug, not the client's fault: still answer in words, then close
        log.exception("live try-on failed")
        await _send_error(ws, f"internal error ({type(e).__name__}): {e}")


async def _serve(ws: WebSocket) -> None:
    app = ws.app
    try:
        raw = await asyncio.wait_for(ws.receive(), timeout=REQUEST_TIMEOUT_S)
    except asyncio.TimeoutError:
        await _send_error(ws, f"no request received within {REQUEST_TIMEOUT_S:.0f} s")
        return
    except (WebSocketDisconnect, RuntimeError):
        return
    if raw["type"] == "websocket.disconnect":
        return
    text = raw.get("text")
    if text is None:
        await _send_error(ws, "expected one JSON text message with the try-on request, got binary data")
        return
    try:
        payload = json.loads(text)
    except json.JSONDecodeError as e:
        await _send_error(ws, f"the request is not valid JSON: {e.msg} at line {e.lineno} column {e.colno}")
        return
    except RecursionError:
        await _send_error(ws, "the request is not usable JSON: it is nested too deeply")
        return
    if not isinstance(payload, dict):
        await _send_error(ws, "the request must be a JSON object with garment_id, measurements, pose, settings")
        return
    try:
        request = LiveTryOnRequest.model_validate(payload)
    except ValidationError as e:
        await _send_error(ws, validation_reason(e))
        return

    # an unknown (or deleted) garment: said at once, before the result cache (which may still hold a
    # deleted garment's try-on) and without taking a pool slot (a busy server would answer "busy")
    if get_catalogue(ws).get(request.garment_id) is None:
        await _send_error(ws, failure_reason(KeyError(request.garment_id), request))
        return

    cache = get_result_cache(app)
    key = tryon_key(request)
    cached = cache.get(key)
    if cached is not None:
        try:
            await _replay(ws, cached, request, get_catalogue(ws))
        except (WebSocketDisconnect, RuntimeError, OSError):
            pass
        return

    pool = get_pool(app)
    session = LiveSession(asyncio.get_running_loop(), request.fps)
    guard = pool.guard(cancelled=session.cancelled, on_frame=session.on_frame)
    try:
        future = pool.submit(run_live, get_catalogue(ws), request, session, guard)
    except PoolFull as e:
        await _send_error(ws, str(e), code=CLOSE_TRY_AGAIN_LATER)
        return
    session.future = future

    sender = asyncio.create_task(_sender(ws, session))
    watcher = asyncio.create_task(_watch_disconnect(ws, session))
    try:
        try:
            outcome = await asyncio.wrap_future(future)
        except (asyncio.CancelledError, FutureCancelled, RunCancelled):
            if session.cancelled.is_set():
                return  # the client left (before or while the job ran): nothing to send
            session.stop()
            raise
        except Exception as e:  # the simulation failed: tell the client in words
            session.stop()
            await sender
            await _send_error(ws, failure_reason(e, request))
            return
        if session.cancelled.is_set():
            return  # client gone: nothing to send, nothing to cache (the run was cut short)
        run, done = outcome
        session.finish(done["metrics"].get("steps", 0), run.result.vertices)
        await sender
        if session.cancelled.is_set():
            return
        done = {**done, "frames_sent": session.frames_sent,
                "time_to_first_frame_s": round((session.first_frame_at or time.monotonic()) - session.started_at, 4),
                "bytes_sent": session.bytes_sent}
        if guard.stopped_by is None:
            cache.put(key, run)
        try:
            await ws.send_text(json.dumps(done, separators=(",", ":")))
        except (WebSocketDisconnect, RuntimeError, OSError):
            return
        await _close(ws)
    finally:
        session.stop()
        for task in (sender, watcher):
            if not task.done():
                task.cancel()
