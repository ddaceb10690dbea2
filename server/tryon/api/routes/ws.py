"""``WS /ws/tryon``: a live try-on, streamed while the garment drapes (SPEC section 6).

Protocol (one try-on per connection):

1. the client sends one JSON text message: the same body as ``POST /api/tryon`` plus an optional
   ``fps`` (frames per second of wall time it wants, 1-60, default 30) and ``encoding`` (float32 |
   uint16, default float32);
2. the server answers one JSON ``{"type": "init", ...}``: the garment's full-mesh ``faces`` and
   ``vertex_count``, the ``body`` mesh, the garment's catalogue entry and the frame ``encoding``; for an
   outfit (``garment_ids``) the faces and vertices of every garment one after the other, and ``garments``:
   each garment's catalogue entry and its ``vertex_start`` / ``vertex_count`` / ``face_start`` / ``face_count``,
   innermost first;
3. then binary frames, each the FULL mesh's vertex positions (an outfit's: all its garments'): a 12-byte
   header (little-endian uint32 frame number, counting 0, 1, 2, ... over the frames sent; uint32 simulation
   step; float32 seconds since the request was accepted) followed by ``vertex_count * 3`` little-endian
   float32 x, y, z in metres (``12 + 12 * vertex_count`` bytes). The last frame is the final state. With
   ``"encoding": "uint16"`` in the request the positions are uint16 q instead, position = origin + q * scale
   (metres, per axis; origin and scale in the init message's ``encoding``): half the bytes. The frames start
   once the garment is on the whole body: the start-up, where the body is grown into a garment put on tangled
   with it and the arms are turned back from the sleeves, is not streamed (``run.settle``);
4. then one JSON ``{"type": "done", "metrics": {...}, "strain": [...], "cached": bool, ...}`` and a
   normal close (1000); an outfit's metrics are ``POST /api/tryon``'s outfit metrics, with ``garments``: each
   garment's own metrics (its strain in ``strain``, every garment's one after the other).

5. with ``"live": true`` (one garment) the connection stays open after done: ``{"type": "pose", "pose": ...}``
   messages re-pose the body with the garment on it; each taken update gets a ``body`` message (its vertices
   in the binary message right after it: float32 x, y, z, no header), frames
   (with ``body_pose`` motions while the body moves) and its own done (docs/live-tryon.md, *Live re-posing*).

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
frame, done with ``"cached": true`` (and ``metrics.wall_seconds`` the time of this answer); a live one then
goes on from the cached final state.
"""

from __future__ import annotations

import asyncio
import json
import logging
import time
from concurrent.futures import CancelledError as FutureCancelled

from fastapi import APIRouter, HTTPException, WebSocket, WebSocketDisconnect
from pydantic import ValidationError
from starlette.websockets import WebSocketState

from tryon.api.deps import get_catalogue
from tryon.api.frames import FrameCodec, encode_frame, frame_due
from tryon.api.live import LiveSession, LiveTryOnRequest, PoseUpdate, done_message, failure_reason, replay_parts, \
    resume_live, run_live, shown_model, with_encoding
from tryon.body.params import Pose
from tryon.sim.outfit import piece_categories
from tryon.api.outfits import check_garments
from tryon.api.pool import CachedTryOn, PoolFull, RunCancelled, get_pool, get_result_cache, tryon_key
from tryon.garment.catalogue import Catalogue

router = APIRouter(tags=["ws"])
log = logging.getLogger(__name__)

CLOSE_NORMAL = 1000
CLOSE_TRY_AGAIN_LATER = 1013  # RFC 6455 registry: "Try Again Later"
# bytes: a close frame is a control frame (at most 125 bytes of payload), 2 of them the close code
MAX_CLOSE_REASON_BYTES = 123
# Seconds to wait for the client's request before giving up on the connection.
REQUEST_TIMEOUT_S = 30.0


def validation_reason(error: ValidationError) -> str:
    """A pydantic error in words, naming each bad field."""
    parts = []
    for e in error.errors():
        where = ".".join(str(x) for x in e.get("loc", ())) or "request"
        parts.append(f"{where}: {e.get('msg', 'invalid')}")
    return "invalid request: " + "; ".join(parts)

async def _sender(ws: WebSocket, session: LiveSession) -> None:
    """Send init, then the latest frame whenever one is due (on a 1 / fps cadence, ``frame_due``) and the
    socket is free, until finished."""
    init_sent = False
    due = -1e9  # the earliest the next frame may go (``frame_due``)
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
                due = frame_due(due, now, session.interval_s)
                if session.first_frame_at is None:
                    session.first_frame_at = now
                session.frames_sent += 1
                session.bytes_sent += len(data)
            if session.finished and session.latest is None:
                return
    except (WebSocketDisconnect, RuntimeError, OSError):
        session.stop()


async def _watch_disconnect(ws: WebSocket, session: LiveSession, live: bool = False) -> None:
    """Read until the client goes away, then stop the simulation. Messages after the request are ignored,
    except a live session's pose updates (``live``): each goes into the session's pose slot (latest wins);
    one that is not a valid update gets an error message, and the session goes on."""
    try:
        while True:
            message = await ws.receive()
            if message["type"] == "websocket.disconnect":
                break
            if live and message.get("text") is not None:
                _pose_update(session, message["text"])
    except (WebSocketDisconnect, RuntimeError, OSError):
        pass
    session.stop()


def _pose_update(session: LiveSession, text: str) -> None:
    """A live session's message: a valid pose update into the slot, anything else an error message."""
    try:
        update = PoseUpdate.model_validate_json(text)
    except ValidationError as e:
        session.post_text(json.dumps({"type": "error", "reason": validation_reason(e).replace(
            "invalid request", "invalid pose update"), "fatal": False}))
        return
    session.offer_pose(Pose(**update.pose.angles()))


async def _live_sender(ws: WebSocket, session: LiveSession) -> None:
    """A live session's sender after the first done: the outbox in order, the frames on a 1 / fps cadence
    (``frame_due``), a frame's body motion (``body_pose``) right before it when it changed."""
    due = -1e9  # the earliest a frame may go: a fixed cadence of 1 / fps (``frame_due``)
    last_motion = None
    try:
        while not session.cancelled.is_set():
            await session.wake.wait()
            session.wake.clear()
            while session.outbox and not session.cancelled.is_set():
                item = session.outbox.popleft()
                if item[0] == "text":
                    await ws.send_text(item[1])
                    continue
                if item[0] == "bytes":  # a body message's vertices, right after it
                    await ws.send_bytes(item[1])
                    session.bytes_sent += len(item[1])
                    continue
                _, step, payload, motion = item
                while (wait := due - time.monotonic()) > 0:
                    await asyncio.sleep(wait)
                if motion is not None and motion != last_motion:
                    await ws.send_text(motion)
                    last_motion = motion
                now = time.monotonic()
                data = encode_frame(session.frames_sent, step, payload, now - session.started_at)
                await ws.send_bytes(data)
                session.frame_sent.set()
                due = frame_due(due, now, session.interval_s)
                session.frames_sent += 1
                session.bytes_sent += len(data)
    except (WebSocketDisconnect, RuntimeError, OSError):
        session.stop()


async def _live(ws: WebSocket, session: LiveSession) -> None:
    """A live session after its first done: each pose update taken from the slot (the latest, when the last
    one is settled or has given way) is re-posed and settled on the pool, its done queued after its frames;
    until the client goes away."""
    pool = get_pool(ws.app)
    session.live = True
    sender = asyncio.create_task(_live_sender(ws, session))
    running = None
    try:
        while not session.cancelled.is_set():
            taken = session.take_pose()
            if taken is None:
                session.pose_arrived.clear()
                await session.pose_arrived.wait()
                continue
            update, pose, received_at = taken
            guard = pool.guard(cancelled=session.cancelled, on_frame=session.on_frame)
            try:
                running = pool.submit(session.reposing.repose_to, update, pose, received_at, guard)
            except PoolFull as e:
                session.post_text(json.dumps({"type": "error", "reason": str(e), "update": update, "fatal": False}))
                continue
            try:
                done = await asyncio.wrap_future(running)
            except (asyncio.CancelledError, FutureCancelled, RunCancelled):
                return
            except Exception as e:  # this pose failed: say so, keep the session
                session.post_text(json.dumps({"type": "error", "reason": failure_reason(e, None), "update": update,
                                              "fatal": False}))
                continue
            if done is not None:
                session.post_text(json.dumps(done, separators=(",", ":")))
    finally:
        session.stop()
        if running is not None:
            running.cancel()
        sender.cancel()


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
    the final frame, done with ``cached: true``; then a live request (``live``) goes on as a live session from
    the cached final state (``live.resume_live``), else the connection closes."""
    started = time.perf_counter()
    result = cached.result
    model = shown_model(catalogue, request, cached)
    init_base, box = await asyncio.to_thread(lambda: replay_parts(cached, model))
    codec = FrameCodec.around(request.encoding, box)
    await ws.send_text(with_encoding(init_base, codec, len(result.vertices)))
    frame = encode_frame(0, result.metrics.get("steps", 0), result.vertices, codec=codec)
    await ws.send_bytes(frame)
    done = {**done_message(result, None, time.perf_counter() - started), "frames_sent": 1, "bytes_sent": len(frame)}
    if not request.live:
        await ws.send_text(json.dumps(done, separators=(",", ":")))
        await ws.close(code=CLOSE_NORMAL)
        return
    if piece_categories(model) is not None:
        await _send_error(ws, "cannot run this try-on: live re-posing is not available for a garment file of "
                              "several pieces (an outfit): ask without \"live\" to drape it once in a pose")
        return
    session = LiveSession(asyncio.get_running_loop(), request.fps)
    session.frames_sent, session.bytes_sent = 1, len(frame)
    await asyncio.to_thread(resume_live, session, request, model, cached, codec)
    await ws.send_text(json.dumps({**done, "update": 0}, separators=(",", ":")))
    watcher = asyncio.create_task(_watch_disconnect(ws, session, live=True))
    try:
        await _live(ws, session)
    finally:
        session.stop()
        watcher.cancel()


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
    try:
        check_garments(get_catalogue(ws), request)
    except HTTPException as e:
        await _send_error(ws, failure_reason(e, request))
        return

    cache = get_result_cache(app)
    key = tryon_key(request, get_catalogue(ws))
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
    watcher = asyncio.create_task(_watch_disconnect(ws, session, live=request.live))
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
            await ws.send_text(json.dumps({**done, "update": 0} if request.live else done, separators=(",", ":")))
        except (WebSocketDisconnect, RuntimeError, OSError):
            return
        if request.live and session.reposing is not None:
            await _live(ws, session)
            return
        await _close(ws)
    finally:
        session.stop()
        for task in (sender, watcher):
            if not task.done():
                task.cancel()
