"""Outfits (issue 29): every catalogue top over every catalogue bottom, size M, on the small, medium and large
bodies of the fit section, tucked out and in. Per outfit: at rest, garment vertices in the body, outer-garment
vertices on the body's side of a garment under it (``layer_penetrating_vertices``), whether the top's hem is
over (out) or under (in) the bottom's band, sleeves and legs round their limbs, and the time against the sum
of the two garments' single drapes (the issue's bound: 1.5 x). Quick mode: the T-shirt over the trousers on
the medium body."""

from __future__ import annotations

import time

from tryon.bench.common import Context, Section, Table, fmt
from tryon.bench.fit import BODIES
from tryon.bench.scenes import catalogue_entries, prepared

TOPS = ("tshirt-m.obj", "longsleeve-m.obj")
BOTTOMS = ("skirt-m.obj", "trousers-m.obj", "shorts-m.obj")
# The issue's bound on an outfit's cost: its wall time over the sum of its garments' single drapes.
COST_BOUND = 1.5


def run(ctx: Context, sec: Section) -> None:
    from tryon.body.build import build_body
    from tryon.body.params import Measurements, Pose
    from tryon.sim.collision.crossings import self_intersections
    from tryon.sim.outfit import drape_outfit
    from tryon.sim.run import drape
    from tryon.sim.settings import SimSettings

    entries = {e["file"]: e for e in catalogue_entries()}
    tops, bottoms = (TOPS[:1], BOTTOMS[1:2]) if ctx.quick else (TOPS, BOTTOMS)
    bodies = {"medium": BODIES["medium"]} if ctx.quick else BODIES
    settings = SimSettings()
    rows, data = [], []
    for body_name, measurements in bodies.items():
        body = build_body(Measurements(**measurements), Pose())
        single = {}
        for name in tops + bottoms:
            model = prepared(ctx, entries[name])[0]
            t = time.perf_counter()
            drape(body, model, settings)
            single[name] = time.perf_counter() - t
        for top in tops:
            for bottom in bottoms:
                models = [prepared(ctx, entries[top])[0], prepared(ctx, entries[bottom])[0]]
                for tuck in ("out", "in"):
                    t = time.perf_counter()
                    out = drape_outfit(body, models, settings, tuck)
                    wall = time.perf_counter() - t
                    m = out.metrics
                    limbs = all(r.metrics["openings_on_limbs"] is not False for r in out.results)
                    d = {"body": body_name, "top": entries[top]["name"], "bottom": entries[bottom]["name"],
                         "tuck": tuck, "steps": m["steps"], "rest": m["rest_reached"], "wall_s": wall,
                         "single_sum_s": single[top] + single[bottom],
                         "penetrating": sum(r.metrics["penetrating_vertices"] for r in out.results),
                         "layer_penetrating": m["layer_penetrating_vertices"],
                         "max_layer_mm": m["max_layer_penetration_mm"], "tuck_as_asked": m["tuck_as_asked"],
                         "on_limbs": limbs,
                         "springs_over": sum(k["over"] for r in out.results
                                             for k in r.metrics["strain_by_kind"].values()),
                         "self_intersections": sum(self_intersections(r.vertices, r.faces) for r in out.results)}
                    d["cost_ratio"] = d["wall_s"] / max(d["single_sum_s"], 1e-9)
                    data.append(d)
                    rows.append([body_name, d["top"], d["bottom"], tuck, d["steps"], fmt(d["rest"]), fmt(wall),
                                 fmt(d["cost_ratio"]), d["penetrating"], d["layer_penetrating"],
                                 fmt(d["max_layer_mm"]), fmt(d["tuck_as_asked"]), fmt(limbs), d["springs_over"],
                                 d["self_intersections"]])
                    ctx.log(f"  outfit {body_name} {top} over {bottom} ({tuck}): layer {d['layer_penetrating']}, "
                            f"{wall:.2f} s")
    sec.data = {"outfits": data, "cost_bound": COST_BOUND}
    sec.tables.append(Table(
        "A top over a bottom (size M), tucked out and in", [
            "body", "top", "bottom", "tuck", "steps", "at rest", "wall s", "x single drapes", "in body",
            "layer penetrating", "deepest layer mm", "tuck as asked", "sleeves / legs", "springs over",
            "self-crossings"], rows,
        note="x single drapes: the outfit's wall time over the sum of its two garments' single drapes on the same "
             f"body (the issue's bound: {COST_BOUND:g}); in body: garment vertices more than 2 mm inside the body; "
             "layer penetrating: outer-garment vertices more than 2 mm on the body's side of the garment under "
             "it; tuck as asked: the top's points at the band's height lie outside the band (out) or inside it "
             "(in); springs over: both garments' springs beyond their limits; self-crossings: edges of a garment's "
             "shown mesh through one of its own triangles"))
    n = len(data)
    sec.headline.append(
        f"outfits: {n} (top over bottom, out and in), at rest {sum(d['rest'] for d in data)}/{n}, in body "
        f"{sum(d['penetrating'] for d in data)}, layer penetrating {sum(d['layer_penetrating'] for d in data)}, "
        f"tuck as asked {sum(bool(d['tuck_as_asked']) for d in data)}/{n}, cost x single drapes median "
        f"{sorted(d['cost_ratio'] for d in data)[n // 2]:.2f}")
