"""Issue 6, in-process parts: the bounded pool, the run guard (wall-clock limit, cancel), the result cache,
the frame encoding; and through the app in-process, a full pool's refusals and the wall-clock limit (made
certain here: a job that holds the worker until let go, a limit of a microsecond). The end-to-end tests
through a real server are in ``test_ws.py``. No assertion is on time; timeouts only guard against a hang."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from tryon.api.pool import (
    CachedTryOn,
    PoolFull,
    ResultCache,
    RunCancelled,
    RunGuard,
    SimPool,
    busy_response_headers,
    request_key,
)
from tryon.api.frames import FRAME_HEADER, FrameCodec, encode_frame, encoding, frame_due
from tryon.api.routes.ws import MAX_CLOSE_REASON_BYTES, close_reason

HANG_S = 60.0  # a guard against a hang, not a measured limit


def settled(pool: SimPool, **counts) -> dict:
    """The pool's stats once they show ``counts`` (a job's slot and counters are released by its future's
    done callback, which may run just after its result is handed out); polled, ``HANG_S`` guards a hang."""
    deadline = time.monotonic() + HANG_S
    while any((stats := pool.stats())[k] != v for k, v in counts.items()):
        assert time.monotonic() < deadline, stats
        time.sleep(0.005)
    return stats


def test_pool_refuses_at_once_when_full_and_frees_slots():
    pool = SimPool(workers=1, queue=1, wall_limit_s=5.0)
    release = threading.Event()
    try:
        running = pool.submit(release.wait, HANG_S)
        waiting = pool.submit(lambda: "second")
        settled(pool, running=1, waiting=1)  # the first job has its worker
        # refused at once, not after a wait: the running job holds its worker until ``release`` (set only after
        # this), so a submit that waited for a slot would never return (run on a thread: a hang is a failure)
        refused = []
        caller = threading.Thread(target=lambda: refused.append(pytest.raises(PoolFull, pool.submit, lambda: "third")),
                                  daemon=True)
        caller.start()
        caller.join(timeout=HANG_S)
        assert refused, "submit did not refuse at once (it waited for a slot, or took the job)"
        info = refused[0]
        assert info.value.capacity == 2
        assert busy_response_headers(info.value) == {"Retry-After": str(info.value.retry_after_s)}
        stats = pool.stats()
        assert (stats["running"], stats["waiting"], stats["refused"]) == (1, 1, 1)
        release.set()
        assert running.result(timeout=HANG_S) is True
        assert waiting.result(timeout=HANG_S) == "second"
        settled(pool, running=0, waiting=0)
        assert pool.submit(lambda: 3).result(timeout=HANG_S) == 3  # slots came back
        settled(pool, completed=3)
    finally:
        release.set()
        pool.shutdown()


def test_pool_counts_failures_and_cancelled_waiters():
    pool = SimPool(workers=1, queue=1, wall_limit_s=5.0)
    release = threading.Event()
    try:
        blocker = pool.submit(release.wait, HANG_S)
        waiter = pool.submit(lambda: None)
        assert waiter.cancel()  # a waiting job can be cancelled (the client left before it started)
        assert pool.stats()["waiting"] == 0
        release.set()
        blocker.result(timeout=HANG_S)
        with pytest.raises(ZeroDivisionError):
            pool.submit(lambda: 1 / 0).result(timeout=HANG_S)
        guard = RunGuard(5.0)
        guard.cancelled.set()
        with pytest.raises(RunCancelled):
            pool.submit(guard, 0, None).result(timeout=HANG_S)
        settled(pool, running=0, waiting=0, cancelled=2, failed=1)
    finally:
        release.set()
        pool.shutdown()


def test_run_guard_stops_past_the_wall_limit_and_when_cancelled():
    guard = RunGuard(wall_limit_s=0.05)
    x = np.zeros((4, 3))
    assert guard(0, x) is True
    time.sleep(0.06)
    assert guard(1, x) is False and guard.stopped_by == "wall_limit"

    cancel = threading.Event()
    seen = []
    guard = RunGuard(10.0, cancelled=cancel, on_frame=lambda step, c: seen.append(step))
    assert guard(0, x) and guard(1, x)
    cancel.set()
    with pytest.raises(RunCancelled):  # unwinds the drape at once: nobody reads the result
        guard(2, x)
    assert guard.stopped_by == "cancelled"
    assert seen == [0, 1]

    guard = RunGuard(10.0, on_frame=lambda step, c: step < 3)
    assert [guard(s, x) for s in range(5)] == [True, True, True, False, False]
    assert guard.stopped_by == "callback"


def test_request_key_is_canonical():
    m = {"height": 170, "chest": 96.0, "waist": 80, "hips": 100}
    a = request_key("g1", m, {"arm_angle": 30}, {"time_step": 0.02})
    assert a == request_key("g1", dict(reversed(list(m.items()))), {"arm_angle": 30.0}, {"time_step": 0.02})
    assert a != request_key("g2", m, {"arm_angle": 30}, {"time_step": 0.02})
    assert a != request_key("g1", {**m, "hips": 100.5}, {"arm_angle": 30}, {"time_step": 0.02})
    assert a != request_key("g1", m, {"arm_angle": 31}, {"time_step": 0.02})
    assert a != request_key("g1", m, {"arm_angle": 30}, {"time_step": 0.01})


def test_result_cache_is_a_bounded_lru():
    cache = ResultCache(2)
    item = lambda k: CachedTryOn(result={"k": k})
    cache.put("a", item(1))
    cache.put("b", item(2))
    assert cache.get("a").result == {"k": 1}  # a is now the most recent
    cache.put("c", item(3))  # evicts b
    assert cache.get("b") is None and cache.get("c").result == {"k": 3} and len(cache) == 2
    assert cache.stats()["hits"] == 2 and cache.stats()["misses"] == 1
    off = ResultCache(0)
    off.put("a", item(1))
    assert off.get("a") is None


def test_frame_encoding_roundtrip():
    v = np.random.default_rng(0).normal(size=(5, 3))
    data = encode_frame(7, 42, v, 1.25)
    assert len(data) == encoding(5)["bytes_per_frame"] == 12 + 5 * 12
    assert FRAME_HEADER.unpack_from(data) == (7, 42, 1.25)
    back = np.frombuffer(data, dtype="<f4", offset=FRAME_HEADER.size).reshape(-1, 3)
    np.testing.assert_allclose(back, v, rtol=1e-6, atol=1e-7)


def test_frames_keep_their_cadence_when_each_goes_a_little_late():
    """A sender that may send only once a frame is due, every frame 0-8 ms late (a step ending after its slot),
    at 30 fps: 300 frames take 10 s as asked (spaced an interval after each one sent they took 10.7 s, 28
    frames a second), and none follows another by less than half an interval; after a pause the cadence
    starts again from there."""
    interval = 1.0 / 30
    late = np.random.default_rng(0).uniform(0.0, 0.008, 300)
    due, sent, old_due, old_sent = 0.0, [], 0.0, []
    for delay in late:
        sent.append(due + delay)
        due = frame_due(due, sent[-1], interval)
        old_sent.append(old_due + delay)
        old_due = old_sent[-1] + interval  # the rule before: an interval after the frame went
    assert abs((sent[-1] - sent[0]) / 299 - interval) < 1e-4
    assert (old_sent[-1] - old_sent[0]) / 299 > interval + 0.003
    assert np.diff(sent).min() >= 0.5 * interval
    # a 0.3 s pause: the next frame goes when it is ready, the one after no sooner than half an interval later
    assert frame_due(due, due + 0.3, interval) == due + 0.3 + 0.5 * interval


def test_tryon_key_fills_defaults_and_ignores_fps():
    from tryon.api.pool import tryon_key
    from tryon.api.live import LiveTryOnRequest
    from tryon.api.schemas.tryon import TryOnRequest

    body = {"height": 170, "chest": 96, "waist": 82, "hips": 100}
    plain = TryOnRequest(garment_id="g", measurements=body)
    live = LiveTryOnRequest(garment_id="g", measurements={k: float(v) for k, v in body.items()}, fps=12,
                            settings={"max_steps": plain.settings.max_steps})
    assert tryon_key(plain) == tryon_key(live)  # defaults written out or not, ints or floats, any fps
    assert tryon_key(plain) != tryon_key(TryOnRequest(garment_id="g", measurements=body, settings={"max_steps": 7}))
    assert tryon_key(plain) != tryon_key(TryOnRequest(garment_id="g", measurements=body, pose={"arm_angle": 45}))


def test_uint16_frames_quantize_within_the_box():
    rng = np.random.default_rng(1)
    body = rng.uniform([-0.4, 0.0, -0.2], [0.4, 1.8, 0.2], size=(200, 3))
    codec = FrameCodec.around("uint16", body)
    garment = rng.uniform([-0.5, 0.3, -0.3], [0.5, 1.6, 0.3], size=(50, 3))
    data = encode_frame(3, 9, garment, 0.5, codec=codec)
    assert len(data) == codec.describe(50)["bytes_per_frame"] == 12 + 6 * 50
    back = codec.decode(data[12:])
    assert np.abs(back - garment).max() <= max(codec.scale) / 2 + 1e-12  # half a step: ~0.02 mm
    assert max(codec.scale) < 5e-5
    far = codec.decode(codec.encode(np.array([[0.0, 9.0, 0.0]])))
    assert far[0, 1] == pytest.approx(codec.origin[1] + 65535 * codec.scale[1])  # clamped to the box
    assert FrameCodec.around("float32", body).describe(50)["bytes_per_frame"] == 12 + 12 * 50


@pytest.mark.parametrize("reason", ["short reason", "x" * 300, "\u2603" * 60, "e\u0301" * 70])
def test_close_reason_fits_a_close_frame(reason):
    cut = close_reason(reason)
    assert len(cut.encode("utf-8")) <= MAX_CLOSE_REASON_BYTES
    if len(reason.encode("utf-8")) <= MAX_CLOSE_REASON_BYTES:
        assert cut == reason
    else:
        assert cut.endswith("...") and reason.startswith(cut[:-3]) and len(cut) > 30


# --- through the app, in-process: a full pool, the wall-clock limit --------------------------------------------

BODY = {"height": 170.0, "chest": 96.0, "waist": 82.0, "hips": 100.0}
SHORT = {"max_steps": 60}


def _tshirt(data_dir) -> str:
    """A generated T-shirt S ingested into ``data_dir``'s catalogue; its id."""
    from tryon.garment.catalogue import Catalogue
    from tryon.garment.generate import garment_mesh, obj_text

    return Catalogue(data_dir).ingest(obj_text(garment_mesh("tshirt", "S"), "tshirt").encode(), name="T-shirt S",
                                      category="top", size="S", units="m", filename="tshirt-s.obj").id


def _stream(client, request: dict) -> tuple[list[dict], int, int | None]:
    """(the JSON messages, the number of binary frames, the close code) of one ``/ws/tryon`` stream."""
    import json

    messages, frames = [], 0
    with client.websocket_connect("/ws/tryon") as ws:
        ws.send_text(json.dumps(request))
        while (m := ws.receive())["type"] == "websocket.send":
            if m.get("bytes") is not None:
                frames += 1
            else:
                messages.append(json.loads(m["text"]))
    return messages, frames, m.get("code")


def test_a_full_pool_refuses_the_stream_and_the_rest_try_on_and_health_answers(tmp_path):
    """One worker, no waiting slot, held by another job until the test lets it go: a stream is refused (1013,
    "busy", nothing sent before), a REST try-on is a 503 with Retry-After, an unknown garment is still said as
    such (not "busy"), and health answers throughout saying the worker is taken; let go, the worker takes the
    next try-on."""
    from fastapi.testclient import TestClient

    from tryon.api.app import create_app
    from tryon.config import Settings

    gid = _tshirt(tmp_path / "data")
    request = {"garment_id": gid, "measurements": BODY, "settings": SHORT}
    app = create_app(Settings(data_dir=tmp_path / "data", sim_workers=1, sim_queue=0))
    release = threading.Event()
    with TestClient(app) as client:
        from tryon.api.pool import get_pool

        holder = get_pool(app).submit(release.wait, HANG_S)  # another shopper's try-on holds the only worker
        try:
            settled(get_pool(app), running=1)
            messages, frames, code = _stream(client, {**request, "fps": 30})
            assert code == 1013 and frames == 0 and [m["type"] for m in messages] == ["error"], messages
            assert "busy" in messages[0]["reason"]
            messages, frames, code = _stream(client, {**request, "garment_id": "nope"})
            assert code == 1000 and "no garment with id 'nope'" in messages[0]["reason"]  # not "busy"
            r = client.post("/api/tryon", json=request)
            assert r.status_code == 503 and int(r.headers["Retry-After"]) > 0 and "busy" in r.json()["detail"]
            for _ in range(5):
                h = client.get("/api/health")
                assert h.status_code == 200 and h.json()["simulations"]["running"] == 1
            assert h.json()["simulations"]["refused"] == 2
        finally:
            release.set()
        assert holder.result(timeout=HANG_S) is True
        settled(get_pool(app), running=0, waiting=0)
        messages, frames, code = _stream(client, {**request, "fps": 30})
        assert code == 1000 and messages[-1]["type"] == "done" and frames >= 1


def test_the_wall_clock_limit_stops_a_stream_and_says_so(tmp_path, monkeypatch):
    """A service whose wall-clock limit per simulation (``TRYON_SIM_WALL_LIMIT_S``) is a microsecond: a drape
    is past it at its second shown step, so the stream's done says it was stopped by the limit (not at rest,
    short of its step limit), and the cut-short result is not cached (the same request simulates again)."""
    from fastapi.testclient import TestClient

    from tryon.api.app import create_app
    from tryon.config import Settings

    gid = _tshirt(tmp_path / "data")
    monkeypatch.setenv("TRYON_SIM_WALL_LIMIT_S", "0.000001")
    settings = Settings(data_dir=tmp_path / "data")
    assert settings.sim_wall_limit_s == 1e-6
    request = {"garment_id": gid, "measurements": BODY, "settings": SHORT, "fps": 60}
    with TestClient(create_app(settings)) as client:
        for _ in range(2):
            messages, frames, code = _stream(client, request)
            done = messages[-1]
            assert [m["type"] for m in messages] == ["init", "done"] and code == 1000 and frames >= 1
            assert done["cached"] is False and done["timed_out"] is True and done["stopped_by"] == "wall_limit"
            assert done["metrics"]["rest_reached"] is False and 0 < done["metrics"]["steps"] < SHORT["max_steps"]
        health = client.get("/api/health").json()
        assert health["result_cache"]["entries"] == 0  # a cut-short result is not cached
        assert health["simulations"]["wall_limit_s"] == 1e-6 and health["simulations"]["submitted"] == 2
