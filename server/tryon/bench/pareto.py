"""Run time against error (SPEC section 7), and the default settings picked from it.

For a grid of settings (time step, constraint passes, simplification degree B) the main garment is
draped on the size M body; each drape's error is the RMS distance over the full-mesh vertices to a
reference drape of the same scene with an 8x smaller time step and 8x more passes (``REFINE``, at the finest B
of the grid), itself checked against the drape at half its step and twice its passes (the full run). Wall time,
penetration and max strain sit beside each point. The default is the fastest
setting within ``TOLERANCE_MM`` of the reference (or, if none is, within ``TOLERANCE_MM`` of the best
setting's error).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np

from tryon.bench.common import Context, Section, Table, fmt
from tryon.bench.report import plot_xy
from tryon.bench.scenes import default_body, main_entry, prepared

TOLERANCE_MM = 5.0  # RMS error a default may have against the reference (the criterion), mm
# The reference's time step is the grid's finest over this, its passes the grid's most times this. Each halving of
# the step (and doubling of the passes) from the default 0.02 s / 16 moves the T-shirt M's drape less: 22, 7, 5.6
# and 5.5 mm RMS down to 0.00125 s / 256. Ten times (0.002 s / 160 passes) drifted off that sequence: 66 mm RMS from
# each of its drapes, its shown mesh strained to 0.32 (0.17-0.19 theirs), and every grid point 60-84 mm from it.
REFINE = 8
GRID = {
    False: {"time_step": (0.02, 0.03, 0.05), "passes": (4, 8, 16), "simplification": (0.2, 0.3)},
    # quick: two points and a cheap reference (0.0025 s, 32 passes, B = 0.2), ~20 s on this machine
    True: {"time_step": (0.02,), "passes": (2, 4), "simplification": (0.2,)},
}


def scaled(settings, time_step: float, passes: int, simplification: float):
    """``settings`` with a time step and pass count; settings counted in steps (limits, start-up, rest
    detection) are rescaled so that they mean the same simulated time as at the default step."""
    from tryon.sim.settings import SimSettings

    base = SimSettings()
    k = base.time_step / time_step

    def steps(n):
        return max(1, int(math.ceil(n * k)))

    return replace(settings, time_step=time_step, passes=passes, simplification=simplification,
                   max_steps=steps(base.max_steps))


def drape_full(ctx: Context, body, entry, settings):
    from tryon.sim.run import drape

    model, _ = prepared(ctx, entry, settings.simplification)
    res = drape(body, model, settings)
    return res, model


def reference(ctx: Context):
    """(TryOnResult, settings) of the reference drape of the main garment (built once per run): ``REFINE`` x
    smaller time step and ``REFINE`` x more passes than the grid's finest, at its finest B."""
    from tryon.sim.settings import SimSettings

    def make():
        grid = GRID[ctx.quick]
        s = scaled(SimSettings(), min(grid["time_step"]) / REFINE, max(grid["passes"]) * REFINE,
                   max(grid["simplification"]))
        ctx.log(f"[bench]   reference drape: dt {s.time_step} s, {s.passes} passes, B {s.simplification}")
        res, _ = drape_full(ctx, default_body(ctx), main_entry(), s)
        return res, s

    return ctx.cached("reference", make)


def rms_mm(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))) * 1e3)


def run(ctx: Context, sec: Section) -> None:
    from tryon.sim.settings import SimSettings

    grid = GRID[ctx.quick]
    body = default_body(ctx)
    entry = main_entry()
    base = SimSettings()
    ref, ref_settings = reference(ctx)
    points = []
    for dt, passes, b in itertools.product(grid["time_step"], grid["passes"], grid["simplification"]):
        s = scaled(base, dt, passes, b)
        res, model = drape_full(ctx, body, entry, s)
        m = res.metrics
        points.append({
            "time_step": dt, "passes": passes, "simplification": b, "substeps": getattr(s, "substeps", 1),
            "coarse_vertices": len(model.coarse_index),
            "wall_s": m["wall_seconds"], "steps": m["steps"], "rms_mm": rms_mm(res.vertices, ref.vertices),
            "max_penetration_mm": m["max_penetration_mm"], "penetrating_vertices": m["penetrating_vertices"],
            "max_strain": m["max_strain"], "rest_reached": m["rest_reached"],
        })
    within = [p for p in points if p["rms_mm"] <= TOLERANCE_MM]
    # When no setting comes within the tolerance of the reference (the drape's folds differ between
    # settings, which sets a floor under the error), the pick is the fastest within the tolerance of the
    # best setting's error instead: the grid cannot tell those apart.
    best = min(p["rms_mm"] for p in points)
    near_best = [p for p in points if p["rms_mm"] <= best + TOLERANCE_MM]
    pick = min(within or near_best, key=lambda p: p["wall_s"])
    current = next((p for p in points if p["time_step"] == base.time_step and p["passes"] == base.passes
                    and abs(p["simplification"] - base.simplification) < 1e-9), None)
    rm = ref.metrics
    sec.data = {
        "garment": entry["name"], "tolerance_mm": TOLERANCE_MM, "points": points, "pick": pick,
        "pick_within_tolerance": bool(within), "best_rms_mm": best, "current_default": current,
        "reference": {"time_step": ref_settings.time_step, "passes": ref_settings.passes,
                      "simplification": ref_settings.simplification, "substeps": getattr(ref_settings, "substeps", 1),
                      "wall_s": rm["wall_seconds"],
                      "steps": rm["steps"], "rest_reached": rm["rest_reached"],
                      "max_penetration_mm": rm["max_penetration_mm"], "max_strain": rm["max_strain"]},
    }
    if not ctx.quick:
        # Is the reference converged? The same drape at half its step and twice its passes.
        finer, _ = drape_full(ctx, body, entry, scaled(base, ref_settings.time_step / 2, ref_settings.passes * 2,
                                                       ref_settings.simplification))
        check = rms_mm(finer.vertices, ref.vertices)
        sec.data["reference"]["half_step_rms_mm"] = check
        sec.notes.append(
            f"The reference against the same drape at half its step and twice its passes "
            f"({ref_settings.time_step / 2:g} s, {ref_settings.passes * 2} passes, {finer.metrics['steps']} steps, "
            f"{fmt(finer.metrics['wall_seconds'])} s): {fmt(check)} mm RMS apart.")
        # How still is "at rest"? The reference continued to its step limit: how far it creeps on.
        from tryon.sim.run import drape

        model, _ = prepared(ctx, entry, ref_settings.simplification)
        longer = drape(body, model, replace(ref_settings, min_steps=ref_settings.max_steps))
        creep = rms_mm(longer.vertices, ref.vertices)
        sec.data["reference"]["creep_after_rest_mm"] = creep
        sec.notes.append(
            f"The reference, continued past rest to its step limit ({longer.metrics['steps']} steps, "
            f"{fmt(longer.metrics['sim_seconds'])} s simulated), moves on by {fmt(creep)} mm RMS: the error "
            "floor under which settings cannot be told apart with this rest threshold.")
    pareto = _pareto_front(points)
    sec.tables.append(Table(
        f"Settings grid on {entry['name']} (error: RMS over full-mesh vertices vs the reference)",
        ["time step s", "passes", "B", "coarse vertices", "wall s", "steps", "RMS error mm", "max penetration mm",
         "max strain", "rest", "Pareto"],
        [[p["time_step"], p["passes"], p["simplification"], p["coarse_vertices"], fmt(p["wall_s"]), p["steps"],
          fmt(p["rms_mm"]), fmt(p["max_penetration_mm"]), fmt(p["max_strain"]), fmt(p["rest_reached"]),
          "*" if id(p) in pareto else ""] for p in sorted(points, key=lambda q: q["wall_s"])],
        note=(f"Reference: time step {ref_settings.time_step} s, {ref_settings.passes} passes, B "
              f"{ref_settings.simplification}, run to rest: {rm['steps']} steps, {fmt(rm['wall_seconds'])} s, "
              f"rest reached: {fmt(rm['rest_reached'])}. Step-counted "
              "settings (start-up, rest detection, limit) are rescaled to the same simulated time."),
    ))
    verdict = (f"the fastest within {TOLERANCE_MM:g} mm RMS of the reference" if within
               else f"no setting comes within {TOLERANCE_MM:g} mm RMS of the reference (best {fmt(best)} mm); "
                    f"the fastest within {TOLERANCE_MM:g} mm of that best")
    sec.headline.append(
        f"default pick ({verdict}): time step "
        f"{pick['time_step']} s, {pick['passes']} passes, B = {pick['simplification']}: {fmt(pick['wall_s'])} s "
        f"to rest, {fmt(pick['rms_mm'])} mm RMS"
        + (f" (current default {base.time_step} s / {base.passes} / {base.simplification}: "
           f"{fmt(current['wall_s'])} s, {fmt(current['rms_mm'])} mm)" if current else "")
    )
    series = {}
    labels = {}
    for b in sorted({p["simplification"] for p in points}):
        pts = [p for p in points if p["simplification"] == b]
        series[f"B = {b}"] = ([p["wall_s"] for p in pts], [p["rms_mm"] for p in pts], "o")
        labels[f"B = {b}"] = [f"{p['time_step']}/{p['passes']}" for p in pts]
    front = sorted((p for p in points if id(p) in pareto), key=lambda p: p["wall_s"])
    series["Pareto front"] = ([p["wall_s"] for p in front], [p["rms_mm"] for p in front], "k--")
    series[f"{TOLERANCE_MM:g} mm"] = ([min(p["wall_s"] for p in points), max(p["wall_s"] for p in points)],
                                     [TOLERANCE_MM, TOLERANCE_MM], "r:")
    sec.plots.append(plot_xy(ctx.out_dir, "pareto.png", series, "wall time to rest (s)",
                             "RMS error vs reference (mm)",
                             f"Run time against error ({entry['name']}; labels: time step s / passes)",
                             logx=True, logy=True, labels=labels, highlight=(pick["wall_s"], pick["rms_mm"], "pick")))


def _pareto_front(points: list[dict]) -> set:
    """ids of the points no other point beats on both wall time and error."""
    front = set()
    for p in points:
        if not any(q["wall_s"] <= p["wall_s"] and q["rms_mm"] <= p["rms_mm"] and q is not p
                   and (q["wall_s"] < p["wall_s"] or q["rms_mm"] < p["rms_mm"]) for q in points):
            front.add(id(p))
    return front
