"""Fit in other poses: the catalogue's S, M and L garments on the medium body with the arms hanging, raised
and bent and the legs apart (``tryon.body.params.POSE_RANGES``), the same targets as the fit section. The
garments are made for the default pose (arms at 30 degrees, legs at 3): a sleeve at another angle than
its arm is followed by posing the arm along it and turning it back, carrying the sleeve
(``sim/arms.py``). Tops are tried in the arm poses, bottoms in the leg poses, dresses in both. Arms asked
to hang lower than they can rest against the torso are raised to there by ``build_body`` (the medium
body's to about 13 degrees); the table gives the pose built. Quick mode: the main garment in two arm poses.
"""

from __future__ import annotations

from tryon.bench.common import Context, Section, Table, fmt
from tryon.bench.fit import BODIES, _limbs, _stays_up
from tryon.bench.scenes import catalogue_entries, main_entry, prepared

ARM_POSES = [{"arm_angle": a} for a in (0.0, 10.0, 20.0, 45.0, 70.0, 90.0)] + \
    [{"elbow_bend": e} for e in (45.0, 90.0, 120.0)] + \
    [{"arm_angle": 60.0, "elbow_bend": 60.0}, {"arm_angle": 15.0, "elbow_bend": 100.0}]
LEG_POSES = [{"leg_spread": s} for s in (0.0, 10.0, 20.0)]
SIZES = ("S", "M", "L")


def _poses(category: str) -> list[dict]:
    return {"top": ARM_POSES, "bottom": LEG_POSES}.get(category, ARM_POSES + LEG_POSES)


def _pose_name(asked: dict, built: dict) -> str:
    """'arm_angle 0 (built 12.7)' where the body raised the arm (see the module doc), else the angles asked."""
    def as_built(k):  # the shorthand asked (both sides alike): the left side's built angle
        return built[k] if k in built else built[f"{k}_left"]

    return ", ".join(f"{k} {v:g}" + (f" (built {as_built(k):.1f})" if abs(as_built(k) - v) > 0.05 else "")
                     for k, v in asked.items())


def run(ctx: Context, sec: Section) -> None:
    from dataclasses import replace

    from tryon.body.build import build_body
    from tryon.body.params import Measurements, Pose
    from tryon.sim.run import drape

    if ctx.quick:
        jobs = [(main_entry(), p) for p in ({"arm_angle": 10.0}, {"elbow_bend": 90.0})]
    else:
        jobs = [(e, p) for e in catalogue_entries() if e.get("size") in SIZES for p in _poses(e["category"])]
    bodies = {}
    rows, data = [], []
    for entry, pose in jobs:
        key = tuple(sorted(pose.items()))
        if key not in bodies:
            bodies[key] = build_body(Measurements(**BODIES["medium"]), replace(Pose(), **pose))
        model, _ = prepared(ctx, entry)
        m = drape(bodies[key], model).metrics
        kinds = m["strain_by_kind"].values()
        d = {"garment": entry["name"], "pose": pose, "steps": m["steps"], "rest": m["rest_reached"],
             "penetrating": m["penetrating_vertices"], "over": sum(k["over"] for k in kinds),
             "over_on_body": sum(k.get("over_on_body", 0) for k in kinds),
             "display_max_strain": m["display_max_strain"], "on_limbs": m["openings_on_limbs"],
             "off_limbs": [o["opening"] for o in m["limb_openings"] if not o["ok"]],
             "arm_turn_deg": m["arm_turn_deg"], "elbow_turn_deg": m["elbow_turn_deg"],
             "built_arm_angle": m["pose"]["arm_angle_left"], "slid_cm": m["slid_cm"], "stays_up": m["stays_up"]}
        d["met"] = d["over"] == 0 and d["penetrating"] == 0 and d["rest"] and d["on_limbs"] is not False
        data.append(d)
        rows.append([entry["name"], _pose_name(pose, m["pose"]), d["steps"], fmt(d["rest"]),
                     d["penetrating"], d["over"], d["over_on_body"], fmt(d["display_max_strain"]), _limbs(d),
                     _stays_up(d), fmt(d["met"])])
        ctx.log(f"  poses {entry['name']} {pose}: over {d['over']}, limbs {d['on_limbs']}")
    sec.data = {"body": BODIES["medium"], "drapes": data}
    sec.tables.append(Table(
        "Garments on the medium body in other poses (default settings)",
        ["garment", "pose (degrees)", "steps", "at rest", "penetrating", "springs over", "over on body",
         "shown mesh max strain", "sleeves / legs", "stays up", "meets every target"], rows,
        note="the pose's other angles are the default (arms 30, elbows 0, legs 3 degrees); columns as in the "
             "fit section"))
    by_pose = {}
    for d in data:
        name = ", ".join(f"{k} {v:g}" for k, v in d["pose"].items())
        met, n = by_pose.get(name, (0, 0))
        by_pose[name] = (met + d["met"], n + 1)
    sec.headline.append(
        f"poses: {len(data)} drapes on the medium body, meeting every target {sum(d['met'] for d in data)}, "
        f"sleeves and legs around their limbs {sum(d['on_limbs'] is not False for d in data)}, staying up "
        f"{sum(d['stays_up'] for d in data)}; by pose: "
        + ", ".join(f"{k} {m}/{n}" for k, (m, n) in by_pose.items()))
