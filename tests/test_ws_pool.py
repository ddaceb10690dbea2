"""Issue 6, in-process parts: the bounded pool, the run guard (wall-clock limit, cancel), the result cache,
the frame encoding. The end-to-end tests through a real server are in ``test_ws.py``."""

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


def test_pool_refuses_at_once_when_full_and_frees_slots():
    pool = SimPool(workers=1, queue=1, wall_limit_s=5.0)
    release = threading.Event()
    try:
        running = pool.submit(release.wait, 5.0)
        waiting = pool.submit(lambda: "second")
        t0 = time.monotonic()
        with pytest.raises(PoolFull) as info:
            pool.submit(lambda: "third")
        assert time.monotonic() - t0 < 0.05  # refused at once, not after a wait
        assert info.value.capacity == 2
        assert busy_response_headers(info.value) == {"Retry-After": str(info.value.retry_after_s)}
        stats = pool.stats()
        assert (stats["running"], stats["waiting"], stats["refused"]) == (1, 1, 1)
        release.set()
        assert running.result(timeout=5) is True
        assert waiting.result(timeout=5) == "second"
        deadline = time.monotonic() + 2
        while pool.stats()["running"] + pool.stats()["waiting"] and time.monotonic() < deadline:
            time.sleep(0.01)
        assert pool.submit(lambda: 3).result(timeout=5) == 3  # slots came back
        assert pool.stats()["completed"] == 3
    finally:
        release.set()
        pool.shutdown()


def test_pool_counts_failures_and_cancelled_waiters():
    pool = SimPool(workers=1, queue=1, wall_limit_s=5.0)
    release = threading.Event()
    try:
        blocker = pool.submit(release.wait, 5.0)
        waiter = pool.submit(lambda: None)
        assert waiter.cancel()  # a waiting job can be cancelled (the client left before it started)
        assert pool.stats()["waiting"] == 0
        release.set()
        blocker.result(timeout=5)
        with pytest.raises(ZeroDivisionError):
            pool.submit(lambda: 1 / 0).result(timeout=5)
        guard = RunGuard(5.0)
        guard.cancelled.set()
        with pytest.raises(RunCancelled):
            pool.submit(guard, 0, None).result(timeout=5)
        time.sleep(0.05)
        stats = pool.stats()
        assert stats["cancelled"] == 2 and stats["failed"] == 1
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
