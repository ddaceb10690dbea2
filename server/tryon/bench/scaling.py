"""Scaling: time per step against the garment's vertex count (a skirt-like tube around the size M body's
hips, 1k to 50k vertices, simulated at full resolution), against the body's mesh resolution (the main
garment on bodies from coarse to fine), and the time to rest of T-shirts of 7k to 50k vertices as a try-on
runs them (prepared at B = 0.3, the coarse mesh simulated)."""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

from tryon.bench.common import Context, Section, Table, fmt, median_seconds
from tryon.bench.report import plot_xy
from tryon.bench.scenes import default_body, main_entry, prepared
from tryon.sim.blocks import MIN_SPLIT_SPRINGS, machine_threads, parallel_ok, use_threads

GARMENT_SIZES = {False: (1_000, 3_000, 10_000, 25_000, 50_000), True: (1_000, 4_000)}
BODY_RESOLUTIONS = {False: (10, 20, 30, 45, 60), True: (15, 30)}
STEPS_TIMED = {False: 15, True: 5}
WARMUP_STEPS = 10  # steps before timing: the tube starts falling and touching the hips


def tube_model(n_vertices: int, body):
    """A tube ``n_vertices`` strong, 3 cm outside the body's hips, from the waist down to mid-thigh."""
    from tryon.bench.synthetic import cloth_tube

    hips_girth = body.achieved.get("hips", 100.0) / 100.0  # m
    radius = hips_girth / (2 * math.pi) + 0.03
    top = body.levels.get("waist", 1.05)
    length = 0.45
    ratio = 2 * math.pi * radius / length  # around / along, for square-ish cells
    n_around = max(8, int(round(math.sqrt(n_vertices * ratio))))
    n_along = max(2, int(round(n_vertices / n_around)))
    model = cloth_tube(radius, top, top - length, n_around=n_around, n_along=n_along)
    # centre the tube on the torso axis
    torso = body.parts.index("torso")
    axis = body.part_axes[torso]
    shift = np.array([axis[:, 0].mean(), 0.0, axis[:, 2].mean()])
    from dataclasses import replace

    return replace(model, vertices=model.vertices + shift)


def per_step_ms(body, model, steps: int, x0=None) -> float:
    """Median ms per ``drape`` step over ``steps`` steps after ``WARMUP_STEPS`` (start ``x0``, or the
    alignment when None)."""
    from dataclasses import replace

    from tryon.bench.ours_cloth import timed_drape
    from tryon.sim.settings import SimSettings

    settings = replace(SimSettings(), max_steps=WARMUP_STEPS + steps + 1)
    times, _ = timed_drape(body, model, settings, initial=x0)
    return float(np.median(times[WARMUP_STEPS:])) * 1e3


# Grid spacings (m) of the perf generator's T-shirt M (``perf.fine_garment``): ~7,300 vertices (the perf T-shirt),
# ~20,000 and ~49,000; each prepared at B = 0.3 and draped to rest on the perf body (issue 26: the perf T-shirt
# under 0.15 s, a 50,000-vertex garment under 1.5 s). Drapes timed per thread count after a warm-up drape.
REST_SPACINGS = {False: (0.0106, 0.0065, 0.0041), True: (0.0106,)}
REST_REPEATS = {False: 3, True: 1}
# The quick run drapes to rest on one thread only: two threads on a machine where another program keeps a core
# busy took 13 s a drape instead of 0.3 (the threads wait for each other), most of the quick run.
REST_TWO_THREADS = {False: True, True: False}


def rest_rows(spacings, repeats: int, two: bool) -> list[dict]:
    """Wall seconds to rest (median of ``repeats``) of the perf T-shirt made at each grid spacing, on one thread
    and, if ``two``, on two."""
    from tryon.body.build import build_body
    from tryon.body.params import Measurements, Pose
    from tryon.bench.perf import PERF_BODY, fine_garment
    from tryon.sim.run import drape
    from tryon.sim.settings import SimSettings

    body = build_body(Measurements(**PERF_BODY), Pose())
    rows = []
    for spacing in spacings:
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            model = fine_garment(Path(tmp), spacing=spacing)
            prepare_s = time.perf_counter() - t0
        row = {"spacing": spacing, "vertices": len(model.vertices), "particles": len(model.coarse_index),
               "springs": len(model.springs), "prepare_s": prepare_s}  # the first includes compiling what it needs
        for threads in (1, 2) if two else (1,):
            use_threads(threads)
            drape(body, model, SimSettings())  # warm-up: the kernels of this size's blocks
            walls = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                result = drape(body, model, SimSettings())
                walls.append(time.perf_counter() - t0)
            row[f"wall_s_{threads}"] = float(np.median(walls))
            row["steps"] = result.metrics["steps"]
            row["rest_reached"] = result.metrics["rest_reached"]
        use_threads(machine_threads())
        rows.append(row)
    return rows


# the pool's throughput on a large garment: vertices of the tube, simulated steps of each try-on
POOL_TUBE = {False: (10_000, 60), True: (4_000, 20)}


def pool_throughput(body, model, steps: int) -> dict:
    """Try-ons per minute of two drapes of ``model`` (``steps`` steps each) through the service's pool
    (``api.pool.SimPool``, two workers): one after the other (each alone: every core) and both at once
    (one core each), and both at once with every try-on held to one thread from the start."""
    import time
    from dataclasses import replace

    from tryon.api.pool import SimPool
    from tryon.sim.run import drape
    from tryon.sim.settings import SimSettings

    settings = replace(SimSettings(), max_steps=steps, min_steps=steps + 1)

    pool = SimPool(workers=2, queue=2, wall_limit_s=600.0)

    def one(threads=None):
        # as the service runs a try-on: the pool's guard as the frame callback (it sets the thread share)
        guard = pool.guard() if threads is None else None
        if threads is not None:
            use_threads(threads)
        drape(body, model, settings, on_frame=guard, initial=model.vertices.copy())

    try:
        pool.submit(one).result()  # warm
        out = {}
        for name, at_once, threads in (("one after the other", False, None), ("two at once", True, None),
                                       ("two at once, one thread each", True, 1)):
            t = time.perf_counter()
            if at_once:
                jobs = [pool.submit(one, threads) for _ in range(2)]
                for j in jobs:
                    j.result()
            else:
                for _ in range(2):
                    pool.submit(one, threads).result()
            out[name] = 2 * 60.0 / (time.perf_counter() - t)
    finally:
        pool.shutdown()
        use_threads(machine_threads())
    return out


def run(ctx: Context, sec: Section) -> None:
    from tryon.body.build import build_body
    from tryon.body.params import Measurements, Pose
    from tryon.bench.perf import PERF_BODY
    from tryon.bench.scenes import BODY_M

    steps = STEPS_TIMED[ctx.quick]
    body = default_body(ctx)
    garment_rows = []
    two = machine_threads() >= 2 and parallel_ok()
    for n in GARMENT_SIZES[ctx.quick]:
        model = tube_model(n, body)
        use_threads(1)
        ms = per_step_ms(body, model, steps, model.vertices.copy())
        split = len(model.springs) >= MIN_SPLIT_SPRINGS and two
        use_threads(2 if split else 1)
        ms2 = per_step_ms(body, model, steps, model.vertices.copy()) if split else None
        use_threads(machine_threads())
        garment_rows.append({"vertices": len(model.vertices), "springs": len(model.springs), "ms_per_step": ms,
                             "us_per_vertex": ms * 1e3 / len(model.vertices), "ms_per_step_2_threads": ms2})
    body_rows = []
    entry = main_entry()
    model, _ = prepared(ctx, entry)
    for res in BODY_RESOLUTIONS[ctx.quick]:
        m = Measurements(**BODY_M)
        b = default_body(ctx, res)
        build_ms = median_seconds(lambda: build_body(m, Pose(), res), 3, 0) * 1e3
        ms = per_step_ms(b, model, steps)
        body_rows.append({"resolution": res, "body_vertices": len(b.vertices), "body_faces": len(b.faces),
                          "build_ms": build_ms, "ms_per_step": ms})
    rest = rest_rows(REST_SPACINGS[ctx.quick], REST_REPEATS[ctx.quick], two and REST_TWO_THREADS[ctx.quick])
    body_text = ", ".join(f"{k} {v} cm" for k, v in PERF_BODY.items())
    n_pool, pool_steps = POOL_TUBE[ctx.quick]
    pool_model = tube_model(n_pool, body)
    pool = pool_throughput(body, pool_model, pool_steps)
    sec.data = {"garment": garment_rows, "body": body_rows, "body_garment": entry["name"], "to_rest": rest,
                "pool": {"vertices": len(pool_model.vertices), "springs": len(pool_model.springs),
                         "steps": pool_steps, "tryons_per_minute": pool}}
    sec.tables.append(Table(
        "Time per step against garment vertices (tube around the hips, simulated at full resolution)",
        ["vertices", "springs", "ms per step", "us per vertex", "ms per step, 2 threads"],
        [[r["vertices"], r["springs"], fmt(r["ms_per_step"]), fmt(r["us_per_vertex"]),
          fmt(r["ms_per_step_2_threads"]) if r["ms_per_step_2_threads"] else "-"] for r in garment_rows],
        note=(f"drape's steps, median of {steps} after {WARMUP_STEPS}; default settings; one thread, and two where "
              f"the garment's springs split in two blocks (at least {MIN_SPLIT_SPRINGS:,}: ``sim/blocks.py``, "
              "the same drape on both)."),
    ))
    sec.tables.append(Table(
        f"Time per step against body resolution ({entry['name']}, {len(model.coarse_index)} simulated vertices)",
        ["resolution", "body vertices", "body faces", "body build ms", "ms per step"],
        [[r["resolution"], r["body_vertices"], r["body_faces"], fmt(r["build_ms"]), fmt(r["ms_per_step"])]
         for r in body_rows],
    ))
    sec.tables.append(Table(
        "Time to rest against garment vertices (the perf generator's T-shirt M, prepared at B = 0.3)",
        ["vertices", "simulated vertices", "springs", "steps", "at rest", "s to rest, 1 thread",
         "s to rest, 2 threads"],
        [[r["vertices"], r["particles"], r["springs"], r["steps"], "yes" if r["rest_reached"] else "no",
          fmt(r["wall_s_1"]), fmt(r["wall_s_2"]) if "wall_s_2" in r else "-"] for r in rest],
        note=(f"a try-on's drape (``sim.run.drape``: start, steps to rest, relaxation, shown mesh, metrics) on the "
              f"perf body ({body_text}), median of {REST_REPEATS[ctx.quick]} after a warm-up; the first row is "
              "``python3 -m tryon.bench.perf``'s garment; its preparation (once per garment, cached) is not in the "
              "time. Two threads: the garment's springs split in two blocks where there are enough "
              f"(``sim/blocks.py``, at least {MIN_SPLIT_SPRINGS:,}), the step's other parallel kernels on both "
              "(not in --quick)."),
    ))
    sec.tables.append(Table(
        f"Two try-ons through the pool ({len(pool_model.vertices)}-vertex tube, {pool_steps} steps each, "
        "2 workers)",
        ["how", "try-ons per minute"], [[k, fmt(v)] for k, v in pool.items()],
        note=("one after the other: each runs alone and gets every core (its passes on two threads); two at "
              "once: the pool gives each one core (api/pool.py); the last row holds both to one thread from "
              "the start, the throughput two at once must not fall below."),
    ))
    g = garment_rows
    slope = np.polyfit(np.log([r["vertices"] for r in g]), np.log([r["ms_per_step"] for r in g]), 1)[0]
    sec.data["garment_exponent"] = float(slope)
    sec.headline.append(
        f"scaling: {fmt(g[0]['ms_per_step'])} ms per step at {g[0]['vertices']} garment vertices, "
        f"{fmt(g[-1]['ms_per_step'])} ms at {g[-1]['vertices']} (time ~ vertices^{slope:.2f})"
        + (f"; on two threads {fmt(g[-1]['ms_per_step_2_threads'])} ms at {g[-1]['vertices']}"
           if g[-1]["ms_per_step_2_threads"] else "")
    )
    big = rest[-1]
    sec.headline.append(
        f"to rest: the {rest[0]['vertices']:,}-vertex perf T-shirt {fmt(rest[0]['wall_s_1'])} s on one thread"
        + (f", {fmt(rest[0]['wall_s_2'])} s on two" if "wall_s_2" in rest[0] else "")
        + (f"; a {big['vertices']:,}-vertex T-shirt {fmt(big['wall_s_1'])} s"
           + (f", {fmt(big['wall_s_2'])} s on two" if "wall_s_2" in big else "") if len(rest) > 1 else "")
    )
    sec.plots.append(plot_xy(
        ctx.out_dir, "scaling.png",
        {"garment vertices (body res. default)": ([r["vertices"] for r in g], [r["ms_per_step"] for r in g], "o-"),
         f"body vertices ({entry['name']})": ([r["body_vertices"] for r in body_rows],
                                              [r["ms_per_step"] for r in body_rows], "s-")},
        "vertices", "ms per step", "Time per step", logx=True, logy=True,
    ))
