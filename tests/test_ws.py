"""Issue 6 end to end: the live try-on over a real WebSocket to a real ``tryon serve`` process.

One server for the module (session scope), with a tiny pool (1 worker, no waiting slot) so that overload
is easy to reach, and a short wall-clock limit so that "long" simulations are bounded. Each test starts
from an idle pool (``wait_idle``).
"""

from __future__ import annotations

import json
import statistics
import struct
import time
from dataclasses import dataclass, field

import httpx
import numpy as np
import pytest
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from conftest import ADMIN_TOKEN, serve_process
from tryon.garment.catalogue import Catalogue
from tryon.garment.generate import garment_mesh, obj_text

pytestmark = pytest.mark.e2e

WALL_LIMIT_S = 3.0  # the server's per-simulation limit (TRYON_SIM_WALL_LIMIT_S)
BODY = {"height": 170.0, "chest": 96.0, "waist": 82.0, "hips": 100.0}
SHORT = {"max_steps": 60}  # a quick drape of the T-shirt (a few hundred ms)
# The most work a request may ask for (dense trousers, every vertex simulated, smallest step, most
# passes): ~0.3 s per step, a minute to rest, so it runs until stopped (client gone, or the wall-clock limit).
LONG = {"max_steps": 3000, "time_step": 0.005, "passes": 48, "substeps": 16, "simplification": 1.0}
# Many quick steps (small time step): far more steps per second than frames asked for.
MANY_STEPS = {"max_steps": 3000, "time_step": 0.005}


@dataclass
class Live:
    url: str
    garment_id: str  # a T-shirt, ~2,900 vertices
    long_id: str  # trousers subdivided once, ~20,000 vertices

    @property
    def ws(self) -> str:
        return "ws" + self.url[len("http"):] + "/ws/tryon"

    def health(self) -> dict:
        return httpx.get(f"{self.url}/api/health", timeout=5).json()

    def wait_idle(self, timeout_s: float = 10.0) -> float:
        """Seconds until no simulation runs or waits (fails after ``timeout_s``)."""
        t0 = time.monotonic()
        while True:
            sims = self.health()["simulations"]
            if sims["running"] == 0 and sims["waiting"] == 0:
                return time.monotonic() - t0
            assert time.monotonic() - t0 < timeout_s, f"pool still busy: {sims}"
            time.sleep(0.02)

    def request(self, settings: dict, **body) -> dict:
        garment = self.long_id if settings is LONG else self.garment_id
        return {"garment_id": garment, "measurements": {**BODY, **body}, "settings": settings}


@dataclass
class Stream:
    init: dict | None = None
    frames: list = field(default_factory=list)  # (frame number, step, server time s, bytes)
    done: dict | None = None
    error: dict | None = None
    close_code: int | None = None
    close_reason: str = ""
    started: float = 0.0

    def positions(self, i: int = -1) -> np.ndarray:
        header = self.init["encoding"]["header_bytes"]
        return np.frombuffer(self.frames[i][3], dtype="<f4", offset=header).reshape(-1, 3)


def run_stream(live: Live, message, max_frames: int | None = None, timeout_s: float = 60.0) -> Stream:
    """Send ``message`` (dict: as JSON; str/bytes: as is) and record everything until the close."""
    s = Stream(started=time.monotonic())
    with connect(live.ws, max_size=None, open_timeout=10) as ws:
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


@pytest.fixture(scope="session")
def live(tmp_path_factory) -> Live:
    """A served catalogue with two generated garments: a T-shirt (quick drapes) and trousers (long ones)."""
    root = tmp_path_factory.mktemp("ws")
    data = root / "data"
    ids = []
    for kind, size, category in (("tshirt", "S", "top"), ("trousers", "L", "bottom")):
        source = root / f"{kind}-{size}.obj"
        mesh = garment_mesh(kind, size)
        source.write_text(obj_text(mesh if kind == "tshirt" else mesh.subdivide(), kind))
        ids.append(Catalogue(data).ingest(source, name=f"Test {kind} {size}", category=category, size=size,
                                          units="m").id)
    env = {"TRYON_SIM_WORKERS": "1", "TRYON_SIM_QUEUE": "0", "TRYON_SIM_WALL_LIMIT_S": str(WALL_LIMIT_S)}
    with serve_process(data, env=env) as url:
        yield Live(url, *ids)  # its kernels are warm: health said ok


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
    assert len(s.frames) >= 3
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
    t0 = time.monotonic()
    r = httpx.post(f"{live.url}/api/tryon", json=request, timeout=120)
    assert r.status_code == 200, r.text
    assert time.monotonic() - t0 < 1.0
    rest = r.json()
    rest_metrics = dict(rest["metrics"])
    assert rest_metrics["cached"] is True
    assert rest_metrics["wall_seconds"] < min(0.5, done["metrics"]["wall_seconds"])  # this answer's time
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
    r = httpx.post(f"{live.url}/api/tryon", json=request, timeout=120)
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
    assert fresh.done["cached"] is False and len(fresh.frames) >= 2
    assert all(len(f[3]) == enc["bytes_per_frame"] == 12 + 6 * fresh.init["vertex_count"] for f in fresh.frames)
    q = np.frombuffer(fresh.frames[-1][3], dtype="<u2", offset=12).reshape(-1, 3)
    final = np.asarray(enc["origin"]) + q * np.asarray(enc["scale"])
    assert 0.5 < final[:, 1].mean() < 1.6 and (q > 0).all() and (q < 65535).all()  # nothing clamped


def test_frames_respect_the_requested_rate(live: Live):
    live.wait_idle()
    fps = 8
    # the dense trousers: the T-shirt now comes to rest within ~5 frames at this rate
    request = {**live.request(MANY_STEPS, chest=98.0), "garment_id": live.long_id, "fps": fps}
    s = run_stream(live, request, max_frames=6)
    assert len(s.frames) == 6
    sent = np.array([f[2] for f in s.frames])  # the server's send times (frame header)
    steps = np.array([f[1] for f in s.frames])
    # at most fps frames per second of wall time: on the sender's cadence (``frames.frame_due``) n frames span
    # at least n - 1.5 intervals, and no two come within half an interval (float32 seconds: 1 ms of slack) ...
    assert sent[-1] - sent[0] > (len(sent) - 1.5) / fps - 1e-3, np.diff(sent)
    assert np.diff(sent).min() > 0.5 / fps - 1e-3, np.diff(sent)
    # ... while the simulation ran many steps per frame: the steps in between were not sent
    assert np.diff(steps).mean() >= 2, steps
    live.wait_idle()


def test_client_leaving_half_way_stops_the_simulation(live: Live):
    live.wait_idle()
    before = live.health()["simulations"]
    s = run_stream(live, {**live.request(LONG, chest=99.0), "fps": 30}, max_frames=3)
    assert s.init is not None and len(s.frames) == 3
    left = time.monotonic()
    assert live.health()["simulations"]["submitted"] == before["submitted"] + 1
    freed = live.wait_idle(timeout_s=WALL_LIMIT_S)  # well before the wall-clock limit would stop it
    assert time.monotonic() - left < 1.5, f"simulation kept running {freed:.2f} s after the client left"
    # and the worker is free for the next shopper
    ok = run_stream(live, {**live.request(SHORT, chest=99.5), "fps": 30})
    assert ok.done is not None


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
    s = run_stream(live, message, timeout_s=30)
    assert s.error is not None and words.lower() in s.error["reason"].lower(), s.error
    assert s.init is None and not s.frames and s.done is None
    assert s.close_code == 1000
    assert live.health()["status"] == "ok"  # the server carries on


def test_overload_is_refused_at_once_and_health_stays_fast(live: Live):
    live.wait_idle()
    with connect(live.ws, max_size=None) as busy:
        busy.send(json.dumps({**live.request(LONG, chest=101.0), "fps": 30}))
        assert json.loads(busy.recv(timeout=30))["type"] == "init"
        busy.recv(timeout=30)  # a first frame: it is simulating now
        assert live.health()["simulations"]["running"] == 1

        t0 = time.monotonic()
        refused = run_stream(live, {**live.request(SHORT, chest=102.0), "fps": 30}, timeout_s=10)
        assert time.monotonic() - t0 < 1.0
        assert refused.close_code == 1013 and "busy" in refused.error["reason"]
        unknown = run_stream(live, {"garment_id": "nope", "measurements": BODY}, timeout_s=10)
        assert unknown.close_code == 1000 and "no garment with id 'nope'" in unknown.error["reason"]  # not "busy"
        r = httpx.post(f"{live.url}/api/tryon", json=live.request(SHORT, chest=102.0), timeout=10)
        assert r.status_code == 503 and int(r.headers["Retry-After"]) > 0

        latencies = []
        with httpx.Client(timeout=5) as client:
            for _ in range(20):
                t = time.perf_counter()
                assert client.get(f"{live.url}/api/health").status_code == 200
                latencies.append(time.perf_counter() - t)
                time.sleep(0.02)
        # a few tens of milliseconds while a simulation runs; on 2 cores shared with other work a request or two
        # can wait for the scheduler (one of 20 took 0.58 s in a CI run while another job compiled), so the
        # two slowest are left out
        assert statistics.median(latencies) < 0.05 and sorted(latencies)[-3] < 0.25, latencies
    live.wait_idle(timeout_s=3)


def test_a_deleted_garment_is_not_served_from_the_result_cache(live: Live):
    live.wait_idle()
    auth = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
    source = obj_text(garment_mesh("skirt", "S"), "skirt").encode()
    r = httpx.post(f"{live.url}/api/garments", headers=auth, files={"file": ("skirt-s.obj", source)},
                   data={"name": "Skirt to delete", "category": "bottom", "units": "m"}, timeout=60)
    assert r.status_code in (200, 201), r.text
    request = {"garment_id": r.json()["id"], "measurements": BODY, "settings": {"max_steps": 5}}
    assert run_stream(live, request).done is not None
    assert run_stream(live, request).done["cached"] is True
    assert httpx.delete(f"{live.url}/api/garments/{request['garment_id']}", headers=auth).status_code == 204
    s = run_stream(live, request, timeout_s=10)
    assert s.done is None and s.init is None and "no garment with id" in s.error["reason"]


def test_wall_clock_limit_stops_a_long_simulation_and_says_so(live: Live):
    live.wait_idle()
    cached_before = live.health()["result_cache"]["entries"]
    s = run_stream(live, {**live.request(LONG, chest=103.0), "fps": 2}, timeout_s=WALL_LIMIT_S + 30)
    assert s.done is not None, s.error
    assert s.done["timed_out"] is True and s.done["stopped_by"] == "wall_limit"
    assert s.done["metrics"]["steps"] < LONG["max_steps"]
    assert WALL_LIMIT_S * 0.9 < time.monotonic() - s.started < WALL_LIMIT_S + 10
    assert live.health()["result_cache"]["entries"] == cached_before  # a cut-short result is not cached
