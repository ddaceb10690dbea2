"""Peer engines side by side with ours, in the same run (section "peers").

(a) The classic square cloth dropped on a ball (``cloth_scene``) at 1k, 4k, 10k and 40k particles: Taichi's
explicit mass-spring example on its CPU backend with 1 and with 2 threads (ours uses one), Newton's XPBD and
VBD cloth on the CPU device, and ours.
(b) One catalogue garment on one body: ours (``drape``) and Newton XPBD with the body as a triangle-mesh
collider. Taichi is left out of (b): its example collides with an analytic ball only, and a particle vs
body-mesh collision for it is a project of its own.

Peers run in subprocesses (``peer_taichi``, ``peer_newton``): a crash or a missing package there is a
note in the report, never a failure of the benchmark. Headline: our per-frame time over the fastest
peer's, among the peers whose cloth stretched as much as ours or more (and, beside it, over the fastest
peer at all), and against Taichi at our thread count, with whether our quality (max stretch and max
penetration over all frames) is no worse than its; then ours at Taichi's quality (``equal_quality``): the
cheapest of our settings that match it (the fast projection of the strain limits, more substeps), and what
they cost.
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tryon.bench.cloth_scene import FRAMES, SIZES, WARMUP_FRAMES
from tryon.bench.common import Context, Section, Table, fmt, speed_words
from tryon.bench.equal_quality import (
    at_equal_quality, quality_headline, quality_table, quality_target,
)
from tryon.bench.report import plot_peers
from tryon.sim.blocks import MIN_SPLIT_SPRINGS, machine_threads, parallel_ok, use_threads

PEERS = {
    "taichi": ("taichi", "tryon.bench.peer_taichi"),
    "newton": ("newton", "tryon.bench.peer_newton"),
}
# The peer runs of the ball scene: (engine, label in the report, arguments after the budget).
BALL_RUNS = (
    ("taichi", "taichi (1 thread)", ("1",)),
    ("taichi", "taichi (2 threads)", ("2",)),
    ("newton", "newton xpbd", ("xpbd",)),
    ("newton", "newton vbd", ("vbd",)),
)
# Our thread counts: a cloth of at least ``blocks.MIN_SPLIT_SPRINGS`` springs runs its passes and sweep on
# two threads (``sim.blocks``: the same figures as on one); each is compared with Taichi at the same count.
OUR_THREADS = (1, 2)


def threads_label(engine: str, threads: int) -> str:
    """``engine`` at a thread count, as the table names it ("ours (2 threads)")."""
    return f"{engine} ({threads} thread{'s' if threads > 1 else ''})"
# Wall-time budget (s) of one peer run in the full and the quick benchmark: Newton's CPU device runs
# ~0.1-1 s per frame here, so 300 frames of its 10k cloth would take minutes; the frames it did run
# within the budget give its median (the report says how many).
PEER_BUDGET_S = {False: 90.0, True: 8.0}
# Extra wall time (s) allowed for a peer's import, kernel compilation (Warp's first compile of Newton's
# kernels takes ~2 min; later runs load them from its cache) and scene setup.
PEER_STARTUP_S = 300.0


def peer_available(engine: str) -> str | None:
    """None if the engine can be imported, else why not."""
    module = PEERS[engine][0]
    if importlib.util.find_spec(module) is None:
        return f"{module} is not installed (pip install '.[bench]')"
    return None


def run_peer(engine: str, args: list, budget: float, extra: tuple = ()) -> dict:
    """Run a peer's subprocess (``args``, the wall-time budget in s, then ``extra``); its figures, or
    {'error': why}."""
    cmd = [sys.executable, "-m", PEERS[engine][1], *map(str, args), str(budget), *map(str, extra)]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=budget + PEER_STARTUP_S)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {budget + PEER_STARTUP_S:.0f} s"}
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    if proc.returncode != 0 or not lines:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
        return {"error": f"exit {proc.returncode}: " + " | ".join(tail)}
    return json.loads(lines[-1])


def our_substeps(n: int) -> int:
    """Our time steps per 1/60 s frame on an n x n cloth: one (our default step is 0.02 s) up to 4k
    particles; two for the 1 cm spacing of the 10k cloth, whose impact on the ball otherwise stretches
    it to ~1.9x its length (measured; with two, ~1.4x); four for the 0.5 cm of the 40k cloth (with two it
    stretched to 1.95x, with four 1.53x), the step halving with the spacing."""
    return 1 if n <= 64 else 2 if n <= 100 else 4


def our_thread_counts(n: int) -> tuple[int, ...]:
    """Our thread counts on the n x n cloth: 1, and 2 where its springs split in two blocks (~6 n^2 of them:
    the grid's structural, shear and bending springs) on a machine that can run them (``sim.blocks``)."""
    two = 6 * n * n >= MIN_SPLIT_SPRINGS and machine_threads() >= 2 and parallel_ok()
    return (1, 2) if two else (1,)


def headline_ratio(rows: list[dict], threads: int = 1) -> dict | None:
    """Ours at ``threads`` threads vs the fastest peer with at least our stretch (ties count), vs Taichi at
    the same thread count, and vs the fastest peer at all, for one cloth size. ``ours_stable`` is False when
    our cloth ended non-finite or thrown up."""
    ours = next((r for r in rows if r["engine"] == threads_label("ours", threads) and "error" not in r), None)
    peers = [r for r in rows if not r["engine"].startswith("ours") and "error" not in r and r.get("finite")
             and r.get("outcome") != "thrown up"]
    if ours is None or not peers:
        return None
    fair = [r for r in peers if r["max_stretch"] >= ours["max_stretch"] - 1e-9]
    fastest = min(peers, key=lambda r: r["frame_ms_median"])
    best = min(fair, key=lambda r: r["frame_ms_median"]) if fair else None
    out = {
        "particles": ours["particles"], "threads": threads, "ours_frame_ms": ours["frame_ms_median"],
        "ours_stretch": ours["max_stretch"],
        "ours_outcome": ours.get("outcome"), "ours_stable": ours.get("outcome") in ("on the ball", "slid off"),
        "fastest_peer": fastest["engine"], "fastest_peer_frame_ms": fastest["frame_ms_median"],
        "fastest_peer_stretch": fastest["max_stretch"],
        "speedup_vs_fastest": fastest["frame_ms_median"] / ours["frame_ms_median"],
        "peer": None, "peer_frame_ms": None, "peer_stretch": None, "speedup": None, "ratio": None,
    }
    same = next((r for r in peers if r["engine"] == threads_label("taichi", threads)), None)
    if same is not None:
        out.update({"same_threads_peer": same["engine"], "same_threads_frame_ms": same["frame_ms_median"],
                    "same_threads_speedup": same["frame_ms_median"] / ours["frame_ms_median"],
                    "same_threads_stretch": same["max_stretch"],
                    "same_threads_penetration_mm": same["max_penetration_mm"],
                    "ours_penetration_mm": ours["max_penetration_mm"],
                    "same_threads_quality_ok": bool(ours["max_stretch"] <= same["max_stretch"] + 1e-9 and
                                                    ours["max_penetration_mm"] <= same["max_penetration_mm"] + 1e-9)})
    if best is not None:
        out.update({"peer": best["engine"], "peer_frame_ms": best["frame_ms_median"],
                    "peer_stretch": best["max_stretch"],
                    "speedup": best["frame_ms_median"] / ours["frame_ms_median"],
                    "ratio": ours["frame_ms_median"] / best["frame_ms_median"]})
    return out


def cloth_on_ball(ctx: Context, sec: Section) -> None:
    from tryon.bench.ours_cloth import run_sphere

    sizes = SIZES[:1] if ctx.quick else SIZES
    budget = PEER_BUDGET_S[ctx.quick]
    missing = {e: peer_available(e) for e in PEERS}
    if ctx.quick and not missing["newton"]:
        # Newton's start-up (importing Warp, loading its kernels, capturing the graph) alone takes ~30 s here
        missing["newton"] = "left out of --quick (its start-up alone takes ~30 s on this machine)"
    for engine, why in missing.items():
        if why:
            sec.notes.append(f"{engine} skipped: {why}")
    results = {}
    for n in sizes:
        rows = []
        for threads in our_thread_counts(n):
            ctx.log(f"[bench]   cloth on ball, {n * n} particles: ours, {threads} thread(s)")
            use_threads(threads)
            ours = run_sphere(n, FRAMES, substeps=our_substeps(n), max_seconds=budget * 4)
            ours["engine"] = threads_label("ours", threads)
            ours["params"]["threads"] = threads
            rows.append(ours)
        use_threads(machine_threads())
        for engine, label, extra in BALL_RUNS:
            if missing[engine]:
                continue
            ctx.log(f"[bench]   cloth on ball, {n * n} particles: {label}")
            args = [n, FRAMES] if engine == "taichi" else ["sphere", n, FRAMES]
            r = run_peer(engine, args, budget, extra)
            r["engine"] = label
            r.setdefault("particles", n * n)
            if "error" in r:
                sec.notes.append(f"{label} at {n * n} particles failed: {r['error']}")
            rows.append(r)
        results[str(n * n)] = rows
    sec.data["cloth_on_ball"] = results
    ratios = [h for rows in results.values() for t in OUR_THREADS if (h := headline_ratio(rows, t))]
    sec.data["headline"] = ratios
    sec.plots.append(plot_peers(ctx.out_dir, results))

    table_rows = []
    for rows in results.values():
        for r in rows:
            if "error" in r:
                table_rows.append([r["engine"], r["particles"], "failed", "-", "-", "-", "-", "-", "-", "-", "-"])
                continue
            table_rows.append([
                r["engine"], r["particles"], fmt(r["frame_ms_median"]), r["frames"], r.get("substeps", "-"),
                fmt(r["max_stretch"]), fmt(r.get("final_stretch")),
                fmt(r.get("answer_stretch", r.get("final_stretch"))), fmt(r["max_penetration_mm"]),
                fmt(r.get("final_penetration_mm")), r.get("outcome", fmt(r["on_sphere_at_end"])),
            ])
    sec.tables.append(Table(
        "Cloth dropped on a ball (1 m square, 0.3 m ball, 1/60 s frames)",
        ["engine", "particles", "ms / frame (median)", "frames run", "steps / frame", "max stretch (all frames)",
         "stretch at the last frame", "stretch of the answer", "max penetration over all frames (mm)",
         "penetration at the end (mm)",
         "at the end"],
        table_rows,
        note=(f"Median over frames after {WARMUP_FRAMES} warm-up frames; stretch = largest grid-edge length / rest - 1 "
              f"(the impact included in the max; 'last frame' after {FRAMES} frames, the cloth at rest; 'the "
              "answer': what the engine returns, for ours the last frame after the relaxation every try-on ends "
              "with (sim/relax.py: gravity off, over-long springs only), for the peers their last frame); "
              "penetration = deepest particle inside the true ball. Taichi's example has a frictionless ball (the "
              "cloth slides off); ours uses the default SimSettings friction, Newton's examples mu = 1. No engine "
              "here takes the cloth's crossings of itself out (ours untangles them in a try-on, "
              "``collision/untangle.py``, not on the ball). Threads: "
              "Taichi and ours with 1 and with 2 (ours: the same figures on both, only the time differs; a cloth "
              f"under {MIN_SPLIT_SPRINGS:,} springs keeps one block and runs on one), Warp's CPU kernels one. "
              "Newton runs within a wall-time budget, so "
              "on the larger cloths its figures cover only the frames it reached (see 'frames run')."),
    ))
    sec.headline.extend(ball_headline(h) for h in ratios)
    quality = []
    for n in sizes:
        rows = results[str(n * n)]
        for threads in our_thread_counts(n):
            default = next((r for r in rows if r["engine"] == threads_label("ours", threads)), None)
            if default is None or "error" in default:
                continue
            peer = threads_label("taichi", threads)
            ctx.log(f"[bench]   cloth on ball, {n * n} particles: ours at {peer}'s quality")
            use_threads(threads)
            quality.append(at_equal_quality(n, default, quality_target(rows, peer),
                                            lambda settings, steps, n=n: run_sphere(n, FRAMES, settings,
                                                                                    substeps=steps,
                                                                                    max_seconds=budget * 4),
                                            threads, budget * 4, steps=our_substeps(n)))
        use_threads(machine_threads())
    sec.data["equal_quality"] = quality
    if quality:
        sec.tables.append(quality_table(quality))
        sec.headline.extend(quality_headline(r) for r in quality)


def ball_headline(h: dict) -> str:
    """One cloth size's headline line from ``headline_ratio``'s figures."""
    text = (f"cloth on ball, {h['particles']} particles: {threads_label('ours', h.get('threads', 1))} "
            f"{fmt(h['ours_frame_ms'])} ms/frame")
    if not h["ours_stable"]:
        text += f" but UNSTABLE (ended {h['ours_outcome']})"
    if h["peer"]:
        text += (f"; vs the fastest peer at equal or higher stretch, {h['peer']} {fmt(h['peer_frame_ms'])} ms: "
                 f"{speed_words(h['speedup'])} (stretch {fmt(h['ours_stretch'])} vs {fmt(h['peer_stretch'])})")
    if h.get("same_threads_peer"):
        text += (f"; vs {h['same_threads_peer']} {fmt(h['same_threads_frame_ms'])} ms: "
                 f"{speed_words(h['same_threads_speedup'])}, our quality "
                 f"{'no worse' if h['same_threads_quality_ok'] else 'WORSE'}")
        if "same_threads_stretch" in h:
            worse = lambda ours, its: "worse" if ours > its + 1e-9 else "no worse"  # noqa: E731
            text += (f" (max stretch {fmt(h['ours_stretch'])} vs {fmt(h['same_threads_stretch'])}: "
                     f"{worse(h['ours_stretch'], h['same_threads_stretch'])}; max penetration "
                     f"{fmt(h['ours_penetration_mm'])} vs {fmt(h['same_threads_penetration_mm'])} mm: "
                     f"{worse(h['ours_penetration_mm'], h['same_threads_penetration_mm'])})")
    if h["fastest_peer"] != h["peer"]:
        text += (f"; vs the fastest peer, {h['fastest_peer']} {fmt(h['fastest_peer_frame_ms'])} ms: "
                 f"{speed_words(h['speedup_vs_fastest'])} (its stretch {fmt(h['fastest_peer_stretch'])}, "
                 f"ours {fmt(h['ours_stretch'])})")
    return text


# Garments of scene (b): the skirt starts clear of the body but for its waistband; the T-shirt's sleeves
# start across the arms (our drape poses the arms along them first; a plain solver has to cope).
GARMENT_SCENE = {True: ("skirt-m.obj",), False: ("skirt-m.obj", "tshirt-m.obj")}
# A peer run whose cloth stretched more than this (10x its length) diverged.
DIVERGED_STRETCH = 10.0


def garment_on_body(ctx: Context, sec: Section) -> None:
    """Scene (b): our drape of a catalogue garment vs Newton XPBD with a mesh collider, same start (our
    alignment), as many simulated seconds as our drape took to reach rest."""
    from tryon.bench.scenes import catalogue_entries, default_body, prepared
    from tryon.sim.align import align_garment
    from tryon.sim.collision.collider import BodyCollider
    from tryon.sim.collision.collider import relevant_parts
    from tryon.sim.run import drape
    from tryon.sim.settings import SimSettings

    body = default_body(ctx)
    entries = {e["file"]: e for e in catalogue_entries()}
    settings = SimSettings()
    collider = BodyCollider(body, settings.collision_margin)
    all_rows = []
    for file in GARMENT_SCENE[ctx.quick]:
        if file not in entries:
            sec.notes.append(f"garment on body: {file} is not in the catalogue")
            continue
        model, _ = prepared(ctx, entries[file])
        x0 = align_garment(body, model)
        stamps = []
        t = time.perf_counter()
        res = drape(body, model, settings, on_frame=lambda step, x: stamps.append(time.perf_counter()) is None)
        wall = time.perf_counter() - t
        m = res.metrics
        ours = {
            "garment": model.meta.name, "engine": "ours", "particles": int(len(model.coarse_index)),
            "steps": m["steps"], "time_step": settings.time_step, "sim_seconds": m["sim_seconds"],
            "ms_per_step": float(np.median(np.diff(stamps)) * 1e3) if len(stamps) > 1 else None,
            "ms_per_sim_second": wall / max(m["sim_seconds"], 1e-9) * 1e3, "wall_s": wall,
            "max_stretch": m["max_strain"], "max_penetration_mm": m["max_penetration_mm"],
            "rest_reached": m["rest_reached"], "diverged": False,
        }
        all_rows.append(ours)
        why = peer_available("newton") or ("left out of --quick" if ctx.quick else None)
        if why:
            sec.notes.append(f"newton garment scene skipped: {why}")
            continue
        with tempfile.TemporaryDirectory() as tmp:
            path = str(Path(tmp) / "scene.npz")
            np.savez(path, cloth_vertices=x0, cloth_faces=model.coarse_faces, body_vertices=body.vertices,
                     body_faces=body.faces, edges=model.springs[model.kind == 0].astype(np.int64),
                     rest=model.rest[model.kind == 0])
            n_frames = max(1, int(round(m["sim_seconds"] * 60)))
            r = run_peer("newton", [path, 0, n_frames], PEER_BUDGET_S[ctx.quick])
            r.update({"garment": model.meta.name, "engine": "newton"})
            if "error" in r:
                sec.notes.append(f"newton garment scene ({file}) failed: {r['error']}")
            else:
                final = np.load(path.replace(".npz", "_final.npy"))
                parts = relevant_parts(body.maps, final.min(axis=0), final.max(axis=0), 0.01)
                depth = collider.depth(final, parts, offset=False) if len(parts) else np.zeros(len(final))
                r["max_penetration_mm"] = float(depth.max() * 1e3) if np.isfinite(final).all() else None
                r["ms_per_sim_second"] = r["frame_ms_median"] * 60.0
                r["sim_seconds"] = r["frames"] / 60.0
                r["diverged"] = bool(not r["finite"] or r["max_stretch"] > DIVERGED_STRETCH)
            all_rows.append(r)
    sec.notes.append("taichi garment scene skipped: its example collides with an analytic ball only; "
                     "particles against a body mesh would be new collision code, not Taichi's example")
    sec.data["garment_on_body"] = all_rows
    sec.tables.append(Table(
        "A catalogue garment on the size M body (same aligned start)",
        ["garment", "engine", "particles", "ms per simulated second", "simulated s", "max stretch",
         "max penetration (mm)", "diverged"],
        [[r["garment"], r["engine"], r.get("particles", "-"), fmt(r.get("ms_per_sim_second")),
          fmt(r.get("sim_seconds")), fmt(r.get("max_stretch")), fmt(r.get("max_penetration_mm")),
          "error" if "error" in r else fmt(r.get("diverged"))] for r in all_rows],
        note="Ours: drape to rest (alignment, arm posing, growth, polish and re-attachment included), default "
             "settings; stretch = max spring strain at rest. Newton: XPBD as in its examples (10 substeps of "
             "1/600 s, 10 iterations, 0.1 kg per particle: lighter particles diverged), the body as a static "
             "triangle-mesh collider, stretch = max over frames of the structural springs; diverged = non-finite "
             f"or stretched beyond {DIVERGED_STRETCH:g}x.",
    ))


def run(ctx: Context, sec: Section) -> None:
    cloth_on_ball(ctx, sec)
    garment_on_body(ctx, sec)
