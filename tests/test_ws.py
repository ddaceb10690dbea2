"""Issue 6 end to end: the live try-on over a real WebSocket to a real ``tryon serve`` process.

The session's shared server (``conftest.shared_server``), its catalogue this module's; a client leaving half
way, on a server served in this process (``conftest.served_here``) whose drape can be held. Each test starts
from an idle pool (``wait_idle``). No assertion here is on time (the machine may be shared): what is checked is
what the server does (frames arrive in order on the sender's cadence, a client leaving frees its worker, health
answers while a drape runs); timeouts only guard against a hang. A full pool's refusals and the wall-clock
limit are checked in-process, where they can be made certain (``test_ws_pool.py``).
"""

from __future__ import annotations

import json
import struct
import time
from dataclasses import dataclass, field

import httpx
import numpy as np
import pytest
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from conftest import ADMIN_TOKEN
from tryon.garment.catalogue import Catalogue
from tryon.garment.generate import garment_mesh, obj_text

pytestmark = pytest.mark.e2e

HANG_S = 120.0  # the longest any wait here may take: a guard against a hang, not a measured limit
BODY = {"height": 170.0, "chest": 96.0, "waist": 82.0, "hips": 100.0}
SHORT = {"max_steps": 60}  # a quick drape of the T-shirt (a few hundred ms)
# Many quick steps (small time step) of the T-shirt: hundreds of steps, far more than frames asked for.
MANY_STEPS = {"max_steps": 3000, "time_step": 0.005}


@dataclass
class Live:
    url: str
    garment_id: str  # a T-shirt, ~2,900 vertices

    @property
    def ws(self) -> str:
        return "ws" + self.url[len("http"):] + "/ws/tryon"

    def health(self) -> dict:
        return httpx.get(f"{self.url}/api/health", timeout=5).json()

    def wait_idle(self) -> dict:
        """The pool's counters once no simulation runs or waits (polled; ``HANG_S`` guards against a hang)."""
        deadline = time.monotonic() + HANG_S
        while True:
            sims = self.health()["simulations"]
            if sims["running"] == 0 and sims["waiting"] == 0:
                return sims
            assert time.monotonic() < deadline, f"pool still busy after {HANG_S:.0f} s: {sims}"
            time.sleep(0.02)

    def request(self, settings: dict, **body) -> dict:
        return {"garment_id": self.garment_id, "measurements": {**BODY, **body}, "settings": settings}


@dataclass
class Stream:
    init: dict | None = None
    frames: list = field(default_factory=list)  # (frame number, step, server time s, bytes)
    done: dict | None = None
    error: dict | None = None
    close_code: int | None = None
    close_reason: str = ""

    def positions(self, i: int = -1) -> np.ndarray:
        header = self.init["encoding"]["header_bytes"]
        return np.frombuffer(self.frames[i][3], dtype="<f4", offset=header).reshape(-1, 3)


def run_stream(live: Live, message, max_frames: int | None = None, timeout_s: float = HANG_S) -> Stream:
    """Send ``message`` (dict: as JSON; str/bytes: as is) and record everything until the close."""
    s = Stream()
    with connect(live.ws, max_size=None, open_timeout=HANG_S) as ws:
        ws.send(message if isinstance(message, (str, bytes)) else json.dumps(message))
        try:
            while True:
                m = ws.recv(timeout=timeout_s)
                if isinstance(m, bytes):
                    frame, step, sent_s = struct.unpack_from("<IIf", m)
                    s.frames.append((frame, step, sent_s, m))
                    if max_frames is not None and len(s.frames) >= max_frames:
                        return s  # leave half way: the context manager closes the socket
                    continue
                d = json.loads(m)
                setattr(s, {"init": "init", "done": "done", "error": "error"}[d["type"]], d)
        except ConnectionClosed:
            pass
        s.close_code = ws.close_code
        s.close_reason = ws.close_reason or ""
    return s


@pytest.fixture(scope="module")
def live(shared_server) -> Live:
    """The shared server with a generated T-shirt."""
    with shared_server.stocked("test_ws") as stock:
        gid = stock.add(obj_text(garment_mesh("tshirt", "S"), "tshirt"), "tshirt-S.obj", name="Test tshirt S",
                        category="top", size="S", units="m")
        yield Live(shared_server.url, gid)


def test_full_stream_matches_rest(live: Live):
    live.wait_idle()
    request = live.request(SHORT, chest=97.0)
    s = run_stream(live, {**request, "fps": 60})
    assert s.error is None and s.close_code == 1000
    init, done = s.init, s.done
    n = init["vertex_count"]
    assert n > 1000 and init["garment"]["id"] == live.garment_id and init["garment"]["category"] == "top"
    faces = np.asarray(init["faces"])
    assert faces.shape == (init["face_count"], 3) and faces.min() == 0 and faces.max() == n - 1
    body = init["body"]
    assert len(body["vertices"]) > 1000 and np.asarray(body["faces"]).max() == len(body["vertices"]) - 1
    enc = init["encoding"]
    assert enc["type"] == "float32" and enc["byte_order"] == "little" and enc["header_bytes"] == 12
    assert enc["bytes_per_frame"] == 12 + 12 * n
    assert len(s.frames) >= 1  # the final one at least; frames while it drapes: the rate test below
    assert all(len(f[3]) == enc["bytes_per_frame"] for f in s.frames)
    numbers = [f[0] for f in s.frames]
    steps = [f[1] for f in s.frames]
    assert numbers == list(range(len(numbers))) and steps == sorted(steps)
    assert steps[-1] == done["metrics"]["steps"] and done["cached"] is False and done["metrics"]["cached"] is False
    assert done["frames_sent"] == len(s.frames)
    assert len(done["strain"]) == n
    final = s.positions()
    assert np.isfinite(final).all() and 0.5 < final[:, 1].mean() < 1.6  # on the torso of a 1.7 m body

    # the same request over REST: one cache for both ways in, answered without simulating, and saying so
    submitted = live.health()["simulations"]["submitted"]
    r = httpx.post(f"{live.url}/api/tryon", json=request, timeout=HANG_S)
    assert r.status_code == 200, r.text
    assert live.health()["simulations"]["submitted"] == submitted  # not simulated again
    rest = r.json()
    rest_metrics = dict(rest["metrics"])
    assert rest_metrics["cached"] is True
    assert rest_metrics["wall_seconds"] >= 0  # this answer's own time; the drape's is simulation_wall_seconds
    assert rest_metrics["simulation_wall_seconds"] == done["metrics"]["simulation_wall_seconds"]
    np.testing.assert_allclose(rest_metrics.pop("strain"), done["strain"], atol=1e-4)
    for key in ("steps", "penetrating_vertices", "rest_reached", "sim_seconds", "max_strain"):
        assert rest_metrics[key] == done["metrics"][key], key
    assert rest["garment"]["faces"] == init["faces"]
    np.testing.assert_allclose(np.asarray(rest["garment"]["vertices"]), final, atol=2e-4)  # JSON rounding

    again = run_stream(live, {**request, "fps": 60})  # the same request: from the result cache
    assert again.done["cached"] is True and again.done["metrics"]["cached"] is True and len(again.frames) == 1
    assert again.frames[0][3][12:] == s.frames[-1][3][12:]
    same = ("wall_seconds", "cached")
    assert {k: v for k, v in again.done["metrics"].items() if k not in same} == \
        {k: v for k, v in done["metrics"].items() if k not in same}


def test_a_stream_replays_a_rest_try_on(live: Live):
    live.wait_idle()
    request = live.request(SHORT, chest=97.2)
    r = httpx.post(f"{live.url}/api/tryon", json=request, timeout=HANG_S)
    assert r.status_code == 200 and r.json()["metrics"]["cached"] is False
    rest = r.json()
    submitted = live.health()["simulations"]["submitted"]
    s = run_stream(live, {**request, "fps": 60, "encoding": "uint16"})
    assert s.error is None and s.done["cached"] is True and len(s.frames) == 1
    assert live.health()["simulations"]["submitted"] == submitted  # not simulated again
    assert s.init["garment"]["id"] == live.garment_id and len(s.init["body"]["vertices"]) > 1000
    assert s.init["faces"] == rest["garment"]["faces"]
    enc = s.init["encoding"]
    q = np.frombuffer(s.frames[0][3], dtype="<u2", offset=12).reshape(-1, 3)
    np.testing.assert_allclose(np.asarray(enc["origin"]) + q * np.asarray(enc["scale"]),
                               np.asarray(rest["garment"]["vertices"]), atol=2e-4)
    assert s.done["metrics"]["steps"] == rest["metrics"]["steps"]


def test_uint16_frames_match_float32(live: Live):
    live.wait_idle()
    request = live.request(SHORT, chest=97.5)
    exact = run_stream(live, {**request, "fps": 60})
    quant = run_stream(live, {**request, "fps": 60, "encoding": "uint16"})
    enc = quant.init["encoding"]
    assert quant.done["cached"] is True  # the encoding is not part of the result: served from the cache
    assert {**quant.init, "encoding": None} == {**exact.init, "encoding": None}
    assert enc["type"] == "uint16" and enc["bytes_per_frame"] == 12 + 6 * quant.init["vertex_count"]
    assert all(len(f[3]) == enc["bytes_per_frame"] for f in quant.frames)
    q = np.frombuffer(quant.frames[-1][3], dtype="<u2", offset=12).reshape(-1, 3)
    positions = np.asarray(enc["origin"]) + q * np.asarray(enc["scale"])
    np.testing.assert_allclose(positions, exact.positions(), atol=max(enc["scale"]))  # ~0.04 mm

    fresh = run_stream(live, {**live.request(SHORT, chest=97.7), "fps": 60, "encoding": "uint16"})
    enc = fresh.init["encoding"]
    assert fresh.done["cached"] is False and len(fresh.frames) >= 1
    assert all(len(f[3]) == enc["bytes_per_frame"] == 12 + 6 * fresh.init["vertex_count"] for f in fresh.frames)
    q = np.frombuffer(fresh.frames[-1][3], dtype="<u2", offset=12).reshape(-1, 3)
    final = np.asarray(enc["origin"]) + q * np.asarray(enc["scale"])
    assert 0.5 < final[:, 1].mean() < 1.6 and (q > 0).all() and (q < 65535).all()  # nothing clamped


def test_frames_respect_the_requested_rate(live: Live):
    """At 2 fps a drape of over a hundred steps sends a few frames: the first at once, the final one at the end,
    numbered in order, on steps in order, the last one the drape's last step, fewer than the steps (the ones in
    between are not sent). The cadence itself (``frames.frame_due``) is checked on given times, without a
    clock, in ``test_ws_pool``."""
    live.wait_idle()
    s = run_stream(live, {**live.request(MANY_STEPS, chest=98.0), "fps": 2})
    assert s.error is None and s.done is not None and s.done["cached"] is False
    numbers = [f[0] for f in s.frames]
    steps = [f[1] for f in s.frames]
    assert numbers == list(range(len(s.frames))) and s.done["frames_sent"] == len(s.frames) >= 2
    assert steps == sorted(steps) and steps[-1] == s.done["metrics"]["steps"]
    assert len(s.frames) < s.done["metrics"]["steps"], (steps, s.done["metrics"]["steps"])


def test_client_leaving_half_way_stops_the_simulation(tmp_path, monkeypatch):
    """A drape whose client leaves at its first frame: its worker is freed, and the pool counts it cancelled
    (a run that went on would end at rest or at the wall-clock limit, counted completed); the next try-on gets
    the worker. While it runs, health answers, each answer saying the drape is running: the event loop is not
    held by it. Made certain on a real server served here: after its first frame each step of the drape waits
    until its run is cancelled (at most ``HANG_S``, a guard against a hang), so it cannot end by itself first."""
    from conftest import served_here

    from tryon.api import pool as pool_module
    from tryon.api.app import create_app
    from tryon.config import Settings

    step = pool_module.RunGuard.__call__

    def held_until_cancelled(guard, *args):
        if guard.frames >= 1:
            guard.cancelled.wait(HANG_S)
        return step(guard, *args)

    monkeypatch.setattr(pool_module.RunGuard, "__call__", held_until_cancelled)
    data = tmp_path / "data"
    gid = Catalogue(data).ingest(obj_text(garment_mesh("tshirt", "S"), "tshirt").encode(), name="Test tshirt S",
                                 category="top", size="S", units="m", filename="tshirt-s.obj").id
    with served_here(create_app(Settings(data_dir=data, sim_workers=1, sim_queue=0))) as url:
        here = Live(url, gid)
        with connect(here.ws, max_size=None, open_timeout=HANG_S) as ws:
            ws.send(json.dumps({**here.request(SHORT, chest=99.0), "fps": 30}))
            assert json.loads(ws.recv(timeout=HANG_S))["type"] == "init"
            assert isinstance(ws.recv(timeout=HANG_S), bytes)  # a first frame: half way, the client leaves
            with httpx.Client(timeout=HANG_S) as client:
                for _ in range(5):
                    h = client.get(f"{url}/api/health")
                    assert h.status_code == 200 and h.json()["status"] == "ok"
                    assert h.json()["simulations"]["running"] == 1, h.json()
        after = here.wait_idle()  # polled until the worker is free (HANG_S guards against a hang)
        assert (after["submitted"], after["cancelled"], after["completed"]) == (1, 1, 0), after
        # and the worker is free for the next shopper
        monkeypatch.setattr(pool_module.RunGuard, "__call__", step)
        ok = run_stream(here, {**here.request(SHORT, chest=99.5), "fps": 30})
        assert ok.done is not None and ok.done["metrics"]["steps"] > 0


@pytest.mark.parametrize("message, words", [
    ("{not json", "not valid JSON"),
    ("[1, 2, 3]", "JSON object"),
    ("[" * 100_000 + "]" * 100_000, "nested too deeply"),  # was "internal error (RecursionError)"
    (b"\x00\x01", "binary"),
    ({"garment_id": "x", "measurements": {**BODY, "height": 500}}, "height"),
    ({"measurements": BODY}, "garment_id"),
    ({"garment_id": "x", "measurements": BODY, "fps": 0}, "fps"),
    ({"garment_id": "nope", "measurements": BODY}, "nope"),
    ('{"garment_id": "x", "measurements": {"height": NaN, "chest": 96, "waist": 82, "hips": 100}}',
     "height must be a finite number"),
    # a reason longer than a close frame can carry (123 bytes of UTF-8) still closes normally
    ({"garment_id": "\u2603" * 60, "measurements": BODY}, "\u2603" * 60),
])
def test_bad_requests_get_an_error_in_words(live: Live, message, words):
    live.wait_idle()
    s = run_stream(live, message)
    assert s.error is not None and words.lower() in s.error["reason"].lower(), s.error
    assert s.init is None and not s.frames and s.done is None
    assert s.close_code == 1000
    assert live.health()["status"] == "ok"  # the server carries on


def test_a_deleted_garment_is_not_served_from_the_result_cache(live: Live):
    live.wait_idle()
    auth = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
    source = obj_text(garment_mesh("skirt", "S"), "skirt").encode()
    r = httpx.post(f"{live.url}/api/garments", headers=auth, files={"file": ("skirt-s.obj", source)},
                   data={"name": "Skirt to delete", "category": "bottom", "units": "m"}, timeout=HANG_S)
    assert r.status_code in (200, 201), r.text
    request = {"garment_id": r.json()["id"], "measurements": BODY, "settings": {"max_steps": 5}}
    assert run_stream(live, request).done is not None
    assert run_stream(live, request).done["cached"] is True
    assert httpx.delete(f"{live.url}/api/garments/{request['garment_id']}", headers=auth).status_code == 204
    s = run_stream(live, request)
    assert s.done is None and s.init is None and "no garment with id" in s.error["reason"]
