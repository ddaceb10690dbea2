"""Live re-posing (issue 30) through a real ``tryon serve`` and a real WebSocket: a live try-on of each garment
on the medium body, then a scripted sequence of pose updates (the named poses, then seeded random ones), each
sent after the last one's done. Per update, on the client's clock: the time to its first frame and to its done
(the garment at rest in the new pose), and what the done says (penetrating vertices, sleeves and legs round
their limbs, whether the carried drape lost a sleeve and was draped afresh, the deepest the cloth went inside
the body on the way: ``motion_max_penetration_mm``). Then the T-shirt M in a session of its own through changes
of 30 degrees (``THIRTY_DEGREES``), the issue's settle target, and in one more a slider dragged (``drag``: updates
sent at a browser's input rate, not waiting for any done): the frames that come while it moves. Quick mode: the
T-shirt, one named pose, one change of 30 degrees, one drag."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from tryon.api.frames import FRAME_HEADER
from tryon.bench.common import Context, Section, Table, fmt
from tryon.bench.fit import BODIES
from tryon.bench.scenes import catalogue_entries, garments_dir

GARMENTS = ("tshirt-m.obj", "longsleeve-m.obj", "trousers-m.obj")
NAMED = ("hands_on_hips", "arms_raised", "stride", "arms_down", "a_pose")
# Random poses after the named ones, per garment (seeded): each side's arm out, forwards and elbow, each leg.
RANDOM_POSES = 5
SEED = 30
# The settle target is for changes of 30 degrees of the T-shirt M: after its other updates the T-shirt
# gets a session of its own through these (each 30 degrees from the one before; quick mode: the first).
THIRTY_DEGREES = ({"arm_angle": 60}, {"arm_angle": 30}, {"arm_angle": 60}, {"arm_angle": 30},
                  {"arm_angle": 30, "elbow_bend": 30}, {"arm_angle": 30}, {"arm_angle": 30, "arm_forward": 30},
                  {"arm_angle": 30})
THIRTY_GARMENT = "tshirt-m.obj"
# A slider dragged: the T-shirt M in a session of its own, both arms from 30 to 60 degrees and back, each drag
# DRAG_UPDATES updates of one degree sent DRAG_RATE a second (a browser's input events, not waiting for any
# done), at the page's frame rate (``web/app.js``: 30 fps). Issue 30: frames at 30 a second while a slider moves.
DRAG_UPDATES = 30
DRAG_RATE = 30.0
DRAG_FPS = 30
# s: the targets (medians of the client's clock): an update's first frame, a 30 degree change at rest.
FIRST_FRAME_TARGET = 0.05
SETTLE_TARGET = 0.5
TIMEOUT_S = 120.0


def random_pose(rng: np.random.Generator) -> dict:
    """One pose within the ranges that a shopper's sliders give (wrists and arm turn left straight)."""
    pose = {}
    for side in ("left", "right"):
        pose[f"arm_angle_{side}"] = round(float(rng.uniform(0.0, 90.0)), 1)
        pose[f"arm_forward_{side}"] = round(float(rng.uniform(0.0, 60.0)), 1)
        pose[f"elbow_bend_{side}"] = round(float(rng.uniform(0.0, 120.0)), 1)
        pose[f"leg_spread_{side}"] = round(float(rng.uniform(0.0, 20.0)), 1)
    return pose


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextmanager
def serving(data_dir: Path, env: dict | None = None, timeout_s: float = TIMEOUT_S, cwd: Path | None = None):
    """``tryon serve`` on a free port over ``data_dir`` (``env``: more environment, ``cwd``: its working
    directory); yields its base URL
    (``http://127.0.0.1:PORT``) once ``/api/health`` says ok, and stops it afterwards. The tests' served
    processes are started by this too (``tests/conftest.py``)."""
    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "tryon.cli", "serve", "--port", str(port), "--log-level",
                             "warning"], env={**os.environ, "TRYON_DATA_DIR": str(data_dir), **(env or {})},
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, cwd=cwd)
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + timeout_s
        while True:
            if proc.poll() is not None:
                raise RuntimeError(f"tryon serve exited: {proc.stdout.read().decode(errors='replace')}")
            try:
                with urllib.request.urlopen(f"{url}/api/health", timeout=1.0) as r:
                    if r.status == 200:
                        break
            except OSError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError("tryon serve did not answer /api/health in time")
            time.sleep(0.1)
        yield url
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()


def _until_done(ws) -> tuple[float | None, float | None, dict]:
    """Read until a done; (client monotonic time of the first binary frame or None, of the first frame of a
    simulated step (step >= 1: not a re-pose's step 0, sent before its drape is set up) or None, the done)."""
    first = stepped = None
    body_follows = False
    while True:
        m = ws.recv(timeout=TIMEOUT_S)
        if isinstance(m, bytes) and body_follows:  # a body message's vertices, not a frame
            body_follows = False
            continue
        if isinstance(m, bytes):
            first = first or time.monotonic()
            if stepped is None and FRAME_HEADER.unpack_from(m)[1] >= 1:
                stepped = time.monotonic()
            continue
        d = json.loads(m)
        body_follows = d["type"] == "body"
        if d["type"] == "error":
            raise RuntimeError(f"live session error: {d}")
        if d["type"] == "done":
            return first, stepped, d


def drag(ws, start: float, end: float, last_update: int) -> dict:
    """Drag the arms' slider from ``start`` to ``end`` degrees over a live session ``ws`` (its first done already
    read): ``DRAG_UPDATES`` updates ``DRAG_RATE`` a second from a thread, frames read meanwhile, until the done of
    the last (the session's update ``last_update``: the server numbers them from 1). The frames that came while
    the slider moved (client clock): how many a second, the median and 95th percentile gap between two; the
    re-poses the server started (its body messages), the dones, the time from the last update to its done and
    that done's checks."""
    frames, bodies, dones, sent = [], 0, [], []

    def send():
        t0 = time.monotonic()
        for k in range(1, DRAG_UPDATES + 1):
            time.sleep(max(0.0, t0 + (k - 1) / DRAG_RATE - time.monotonic()))
            ws.send(json.dumps({"type": "pose", "pose": {"arm_angle": start + (end - start) * k / DRAG_UPDATES}}))
        sent.append(time.monotonic())

    t0 = time.monotonic()
    sender = threading.Thread(target=send)
    sender.start()
    body_follows = False
    while True:
        m = ws.recv(timeout=TIMEOUT_S)
        now = time.monotonic()
        if isinstance(m, bytes):
            if not body_follows:
                frames.append(now)
            body_follows = False
            continue
        d = json.loads(m)
        if d["type"] == "error":
            raise RuntimeError(f"live session error: {d}")
        body_follows = d["type"] == "body"
        bodies += body_follows
        if d["type"] == "done":
            dones.append(d)
            if d["update"] == last_update:
                break
    sender.join()
    moving = [t for t in frames if t <= sent[0]]
    gaps = np.diff([t0] + moving)
    m = dones[-1]["metrics"]
    return {"from": start, "to": end, "updates": DRAG_UPDATES, "drag_s": sent[0] - t0, "frames": len(moving),
            "frames_per_s": len(moving) / (sent[0] - t0), "gap_median_s": float(np.median(gaps)),
            "gap_p95_s": float(np.percentile(gaps, 95)), "reposes": bodies, "dones": len(dones),
            "done_after_s": now - sent[0], "penetrating": m.get("penetrating_vertices"),
            "on_limbs": m.get("openings_on_limbs"), "motion_mm": m.get("motion_max_penetration_mm")}


def run(ctx: Context, sec: Section) -> None:
    from websockets.sync.client import connect

    from tryon.garment.catalogue import Catalogue

    entries = {e["file"]: e for e in catalogue_entries()}
    garments = GARMENTS[:1] if ctx.quick else GARMENTS
    rng = np.random.default_rng(SEED)
    rows, data = [], []
    with tempfile.TemporaryDirectory() as tmp:
        catalogue = Catalogue(Path(tmp) / "data")
        ids = {}
        for name in garments:
            e = entries[name]
            ids[name] = catalogue.ingest(garments_dir() / name, name=e["name"], category=e["category"],
                                         size=e.get("size"), units="m").id
        with serving(Path(tmp) / "data") as base:
            url = "ws" + base[len("http"):] + "/ws/tryon"
            sessions = []
            for name in garments:
                poses = list(NAMED[:1] if ctx.quick else NAMED)
                if not ctx.quick:
                    poses += [random_pose(rng) for _ in range(RANDOM_POSES)]
                sessions.append((name, poses, False))
            sessions.append((THIRTY_GARMENT, list(THIRTY_DEGREES[:1] if ctx.quick else THIRTY_DEGREES), True))
            for name, poses, thirty in sessions:
                with connect(url, max_size=None, open_timeout=30) as ws:
                    ws.send(json.dumps({"garment_id": ids[name], "measurements": BODIES["medium"], "live": True,
                                        "encoding": "uint16"}))
                    _until_done(ws)
                    for i, pose in enumerate(poses):
                        t0 = time.monotonic()
                        ws.send(json.dumps({"type": "pose", "pose": pose}))
                        first, stepped, done = _until_done(ws)
                        m = done["metrics"]
                        named = sum(isinstance(p, str) for p in poses)
                        label = pose if isinstance(pose, str) else f"30 degrees {i + 1}" if thirty \
                            else f"random {i + 1 - named}"
                        d = {"garment": entries[name]["name"], "pose": label, "thirty_degrees": thirty,
                             "angles": pose, "first_frame_s": None if first is None else first - t0,
                             "first_step_s": None if stepped is None else stepped - t0,
                             "done_s": time.monotonic() - t0, "steps": m.get("steps"),
                             "rest": m.get("rest_reached"), "penetrating": m.get("penetrating_vertices"),
                             "on_limbs": m.get("openings_on_limbs"), "redraped": bool(done.get("redraped")),
                             "motion_mm": m.get("motion_max_penetration_mm"),
                             "server_first_frame_s": done.get("time_to_first_frame_s"),
                             "server_first_step_s": done.get("time_to_first_step_s")}
                        data.append(d)
                        rows.append([d["garment"], d["pose"], fmt(d["first_frame_s"]), fmt(d["first_step_s"]),
                                     fmt(d["done_s"]), d["steps"],
                                     fmt(d["rest"]), d["penetrating"], fmt(d["motion_mm"]), fmt(d["on_limbs"]),
                                     fmt(d["redraped"])])
                        ctx.log(f"  live {d['garment']} {d['pose']}: first frame {fmt(d['first_frame_s'])} s, "
                                f"first step {fmt(d['first_step_s'])} s, "
                                f"done {fmt(d['done_s'])} s, penetrating {d['penetrating']}")
            drags = []
            with connect(url, max_size=None, open_timeout=30) as ws:
                ws.send(json.dumps({"garment_id": ids[THIRTY_GARMENT], "measurements": BODIES["medium"], "live": True,
                                    "encoding": "uint16", "fps": DRAG_FPS, "pose": {"arm_angle": 30}}))
                _until_done(ws)
                for k, (a, b) in enumerate(((30.0, 60.0), (60.0, 30.0))[:1 if ctx.quick else 2]):
                    drags.append(drag(ws, a, b, (k + 1) * DRAG_UPDATES))
                    g = drags[-1]
                    ctx.log(f"  live drag {a:g} -> {b:g}: {fmt(g['frames_per_s'])} frames/s, gap median "
                            f"{fmt(g['gap_median_s'])} s, p95 {fmt(g['gap_p95_s'])}, {g['reposes']} re-poses")
    sec.data = {"body": BODIES["medium"], "updates": data, "drags": drags}
    sec.tables.append(Table(
        "Pose updates over a live WebSocket (medium body, each update sent after the last one's done)",
        ["garment", "pose", "first frame (s)", "first step (s)", "at rest (s)", "steps", "at rest", "penetrating",
         "motion penetration (mm)", "sleeves / legs", "draped afresh"], rows,
        note=("client clock, from sending the update to its first frame and to its done; 'first frame': the "
              "motion's step 0 (the garment where it was, the body still in its old pose), sent once the body is "
              "built, before the drape is set up; 'first step': the frame of its first simulated step; "
              "'motion penetration': "
              "the done's motion_max_penetration_mm, the deepest simulated garment point inside the body as it "
              "was at each step of the way (target under 10 mm); 'draped afresh': the "
              "carried garment had lost a sleeve and the server draped it again in the new pose. Random poses: "
              f"each side's arm out 0-90, forwards 0-60, elbow 0-120, leg 0-20 degrees (seed {SEED}); '30 "
              "degrees': a session of its own, each update 30 degrees from the one before (both arms out 30 <-> 60, "
              "elbows 0 <-> 30, forwards 0 <-> 30), the issue's settle target.")))
    sec.tables.append(Table(
        f"Dragging a slider (T-shirt M, both arms, {DRAG_UPDATES} updates of one degree, {DRAG_RATE:g} a second, "
        f"at {DRAG_FPS} fps)",
        ["arms (degrees)", "drag (s)", "frames while moving", "frames / s", "gap median (s)", "gap p95 (s)",
         "re-poses started", "dones", "done after the last update (s)", "penetrating", "sleeves / legs",
         "motion penetration (mm)"],
        [[f"{g['from']:g} -> {g['to']:g}", fmt(g["drag_s"]), g["frames"], fmt(g["frames_per_s"]),
          fmt(g["gap_median_s"]), fmt(g["gap_p95_s"]), g["reposes"], g["dones"], fmt(g["done_after_s"]),
          g["penetrating"], fmt(g["on_limbs"]), fmt(g["motion_mm"])] for g in drags],
        note=("client clock; 'frames while moving': the frames that came between the first update and the last "
              "(a body message's vertices not counted), the gaps between them from the first update; re-poses "
              "started: the server's body messages (updates arriving while a re-pose moves the body wait, and "
              "the latest wins); a done only for the last update (those given way to get none).")))
    first = [d["first_frame_s"] for d in data if d["first_frame_s"] is not None]
    stepped = [d["first_step_s"] for d in data if d["first_step_s"] is not None]
    settle = [d["done_s"] for d in data]
    thirty = [d["done_s"] for d in data if d["thirty_degrees"]]
    ok = sum(d["penetrating"] == 0 and d["on_limbs"] is not False for d in data)
    motion = [d["motion_mm"] for d in data if d["motion_mm"] is not None]
    sec.headline.append(
        f"live re-posing: {len(data)} pose updates on {len(garments)} garments, first frame median "
        f"{fmt(np.median(first))} s (p95 {fmt(np.percentile(first, 95))}; target {FIRST_FRAME_TARGET}; the "
        f"first simulated step's frame median {fmt(np.median(stepped) if stepped else None)} s, p95 "
        f"{fmt(np.percentile(stepped, 95) if stepped else None)}), at rest "
        f"median {fmt(np.median(settle))} s (p95 {fmt(np.percentile(settle, 95))}); 30-degree changes of the "
        f"T-shirt M at rest median {fmt(np.median(thirty))} s (p95 {fmt(np.percentile(thirty, 95))}, target "
        f"{SETTLE_TARGET}); nothing in the body and every sleeve and leg round its limb in {ok}/{len(data)}, draped afresh "
        f"{sum(d['redraped'] for d in data)}; deepest in the body on the way {fmt(max(motion, default=None))} mm "
        f"(median {fmt(float(np.median(motion)) if motion else None)}); dragging a slider at {DRAG_FPS} fps: "
        f"{', '.join(fmt(g['frames_per_s']) for g in drags)} frames/s (gap p95 "
        f"{', '.join(fmt(g['gap_p95_s']) for g in drags)} s), {sum(g['dones'] for g in drags)} dones for "
        f"{len(drags) * DRAG_UPDATES} updates")
