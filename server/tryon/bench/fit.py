"""Catalogue fit: every catalogue garment draped on a small, a medium and a large body (issue 5's accuracy
targets: at rest no vertex deeper than 2 mm in the body, no spring beyond its type's limit by more than
1 %, every drape at rest, sleeves around arms and trouser legs around legs: ``sim/limbs.py``). Quick
mode: the main garment only.

The bodies span the size chart (``tryon.garment.generate.SIZE_CHART``: S chest 88 / waist 74 / hips 94 cm,
XL 112 / 98 / 112, XXL 120 / 106 / 118): the small body is a size S person, the medium one a size M, the
large one a size XL. A garment smaller than its body (an S skirt's 78 cm waistband, 86 cm at its 10 %
limit, on a 100 cm waist) cannot meet both targets: collision wins, and its springs held over the body
are the "over on body" column, the fit verdict "too tight there".
"""

from __future__ import annotations

import time
from dataclasses import replace

from tryon.bench.common import Context, Section, Table, fmt, median
from tryon.bench.scenes import catalogue_entries, main_entry, prepared

# cm: the three bodies (height, chest, waist, hips).
BODIES = {
    "small": dict(height=158.0, chest=86.0, waist=72.0, hips=92.0),
    "medium": dict(height=170.0, chest=96.0, waist=82.0, hips=100.0),
    "large": dict(height=185.0, chest=112.0, waist=100.0, hips=112.0),
}


def run(ctx: Context, sec: Section) -> None:
    from tryon.body.build import build_body
    from tryon.body.params import Measurements, Pose
    from tryon.sim.collision.collider import BodyCollider
    from tryon.sim.metrics import SLID_LIMIT_CM
    from tryon.sim.settings import SimSettings

    settings = SimSettings() if ctx.substeps is None else SimSettings(substeps=ctx.substeps, passes=ctx.substeps)
    if ctx.projection:
        settings = replace(settings, projection_steps=ctx.projection)
    entries = [main_entry()] if ctx.quick else catalogue_entries()
    rows, data = [], []
    for body_name, measurements in BODIES.items():
        body = build_body(Measurements(**measurements), Pose())
        shown = BodyCollider(body, settings.collision_margin)  # the body a page draws beside the frames
        for entry in entries:
            model, _ = prepared(ctx, entry)
            result, frames = drape_watched(body, model, settings, shown)
            m = result.metrics
            kinds = m["strain_by_kind"].values()
            d = {"body": body_name, "garment": entry["name"], "steps": m["steps"], "rest": m["rest_reached"],
                 "wall_s": m["wall_seconds"], "penetrating": m["penetrating_vertices"],
                 "max_penetration_mm": m["max_penetration_mm"], "body_through": m["body_through_vertices"],
                 "max_body_through_mm": m["max_body_through_mm"], "over": sum(k["over"] for k in kinds),
                 "over_on_body": sum(k.get("over_on_body", 0) for k in kinds), "max_strain": m["max_strain"],
                 "display_max_strain": m["display_max_strain"], "springs": len(model.springs),
                 "on_limbs": m["openings_on_limbs"],
                 "off_limbs": [o["opening"] for o in m["limb_openings"] if not o["ok"]],
                 "slid_cm": m["slid_cm"], "stays_up": m["stays_up"],
                 "self_intersections": m["self_crossings"],
                 "hang_stretch": hang_stretch(model, result.vertices), "fabric": model.fabric.name, **frames}
            data.append(d)
            rows.append([body_name, entry["name"], d["steps"], fmt(d["rest"]), fmt(d["wall_s"]), d["penetrating"],
                         fmt(d["max_penetration_mm"]), d["body_through"], fmt(d["max_body_through_mm"]), d["over"],
                         d["over_on_body"], fmt(d["max_strain"]),
                         fmt(d["display_max_strain"]), _limbs(d), _stays_up(d), d["self_intersections"],
                         fmt(d["frame_depth_mm"]), d["fabric"], fmt(100.0 * d["hang_stretch"])])
            ctx.log(f"  fit {body_name} {entry['name']}: over {d['over']}, penetrating {d['penetrating']}")
    sec.data = {"bodies": BODIES, "substeps": settings.substeps, "passes": settings.passes,
                "projection_steps": settings.projection_steps, "drapes": data}
    sec.tables.append(Table(
        f"Every garment on three bodies ({_settings_words(ctx, settings) or 'default settings'})",
        ["body", "garment", "steps", "at rest", "wall s", "penetrating", "deepest mm", "body through",
         "body through mm", "springs over",
         "over on body", "max strain", "shown mesh max strain", "sleeves / legs", "stays up", "self-crossings",
         "deepest frame mm", "fabric", "hang stretch %"],
        rows,
        note="body through: body vertices showing more than 2 mm through the shown mesh where it covers them "
             "(``sim/show_through.py``), and the deepest; springs over: beyond their type's limit by more than 1 % "
             "(0.2 mm for springs under 2 cm); "
             "over on body: of those, both ends touching the body (the garment is too small there); shown "
             "mesh: the full mesh's edges and quad diagonals (where a coarse triangle cuts across a thin "
             "part, a hand or a foot, the full mesh pushed out around it stretches); sleeves / legs: whether every "
             "sleeve, armhole and trouser leg ends around its own arm or leg (``sim/limbs.py``), else the ones "
             f"that do not, '-' for a garment with none; stays up: whether its top ended within "
             f"{SLID_LIMIT_CM:g} cm of where it was put on, with how far it slid (metrics ``stays_up``, "
             "``slid_cm``: a waistband wider than the hips slides off them, meeting every target where it "
             "lands); self-crossings: edges of the shown mesh through one of its own triangles "
             "(metrics ``self_crossings``, ``collision.crossings.self_intersections``: cloth through its own folds; "
             "the shown mesh's own crossings taken back out by ``collision/untangle.py`` as it is built); deepest frame: the deepest simulated point inside the body in any step a caller "
             "is shown (``run.settle``: all but the start-up, where the body is grown into the garment and the arms "
             "turned from the sleeves; issue 26: at most 2 mm in every streamed frame, not only the answer); "
             "fabric: what the garment is made of (``garment/fabric.py``); hang stretch: the median stretch of the "
             "shown mesh's edges along the hang (steeper than 30 degrees) in the garment's lower half "
             "(``hang_stretch``: real cloth stretches ~1 % under its own weight)"))
    per_body = []
    for body_name in BODIES:
        ds = [d for d in data if d["body"] == body_name]
        met = sum(d["over"] == 0 and d["penetrating"] == 0 and d["rest"] and d["on_limbs"] is not False for d in ds)
        per_body.append(f"{body_name} {met}/{len(ds)} (over {sum(d['over'] for d in ds)})")
    label = ", ".join(["fit"] + ([f"{settings.substeps} substeps"] if ctx.substeps is not None else [])
                      + ([f"{settings.projection_steps} projection steps"] if ctx.projection else []))
    sec.headline.append(
        f"{label}: {len(data)} drapes, penetrating vertices {sum(d['penetrating'] for d in data)}, body through "
        f"{sum(d['body_through'] for d in data)}, at rest "
        f"{sum(d['rest'] for d in data)}/{len(data)}, sleeves and legs around their limbs "
        f"{sum(d['on_limbs'] is not False for d in data)}/{len(data)}, staying up {sum(d['stays_up'] for d in data)}/"
        f"{len(data)}; meeting every target: " + ", ".join(per_body)
        + f"; self-crossing edges {sum(d['self_intersections'] for d in data)} "
        f"({sum(d['self_intersections'] for d in data if d['stays_up'])} on the drapes staying up); a shown frame "
        f"more than 2 mm inside "
        f"{sum(d['frame_depth_mm'] > 2.0 for d in data)}/{len(data)} "
        f"(deepest {fmt(max(d['frame_depth_mm'] for d in data))} mm); hang stretch median "
        f"{fmt(100.0 * median([d['hang_stretch'] for d in data]))} %, largest "
        f"{fmt(100.0 * max(d['hang_stretch'] for d in data))} %")


def hang_stretch(model, vertices) -> float:
    """The median strain (l / l0 - 1) of the shown mesh's edges (``vertices`` (n, 3) m, ``model.faces``) that
    run more than 30 degrees from the horizontal and have both ends below the middle of the garment's height:
    how far hanging cloth stretches under its own weight."""
    import numpy as np

    from tryon.body.measure import mesh_edges

    edges = mesh_edges(model.faces)
    rest = np.linalg.norm(model.vertices[edges[:, 0]] - model.vertices[edges[:, 1]], axis=1)
    along = vertices[edges[:, 0]] - vertices[edges[:, 1]]
    length = np.linalg.norm(along, axis=1)
    middle = 0.5 * (vertices[:, 1].min() + vertices[:, 1].max())
    lower = (vertices[edges[:, 0], 1] < middle) & (vertices[edges[:, 1], 1] < middle)
    hanging = lower & (np.abs(along[:, 1]) >= 0.5 * length) & (rest > 0.0)
    return float(np.median(length[hanging] / rest[hanging] - 1.0)) if hanging.any() else 0.0


def drape_watched(body, model, settings, shown) -> tuple:
    """``run.drape``, watching every frame it shows a caller (``run.settle``: the steps after the start-up):
    (the result, {"frame_depth_mm"}), the deepest coarse point inside ``shown`` (a ``BodyCollider`` of the body)
    in any of them (``metrics.deepest_inside``). The result's ``wall_seconds`` leaves the watching out."""
    from tryon.sim.metrics import deepest_inside
    from tryon.sim.run import drape

    deepest = {"frame_depth_mm": 0.0}
    spent = 0.0

    def watch(step, x):
        nonlocal spent
        t = time.perf_counter()
        deepest["frame_depth_mm"] = max(deepest["frame_depth_mm"], 1000.0 * deepest_inside(shown, x))
        spent += time.perf_counter() - t
        return True

    result = drape(body, model, settings, on_frame=watch)
    # the drape's wall time without the watching
    result.metrics["wall_seconds"] -= spent
    return result, deepest


def _settings_words(ctx: Context, settings) -> str:
    """The section's settings other than the default, in words ("" for none)."""
    words = []
    if ctx.substeps is not None:
        words.append(f"{settings.substeps} substeps of one pass a step")
    if ctx.projection:
        words.append(f"{settings.projection_steps} Newton steps of the fast projection a step")
    return ", ".join(words)


def _stays_up(d: dict) -> str:
    """The fit table's stays-up cell: 'yes' or 'no', and how far the garment slid (cm)."""
    return f"{'yes' if d['stays_up'] else 'no'} ({d['slid_cm']:.0f} cm)"


def _limbs(d: dict) -> str:
    """The fit table's sleeves / legs cell."""
    if d["on_limbs"] is None:
        return "-"
    return "around" if d["on_limbs"] else "off: " + ", ".join(d["off_limbs"])
