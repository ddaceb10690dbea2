"""Motion stress (issue 30, "Move in it"): seeded random pose sequences on every catalogue garment, the medium
body, through the sim-level re-pose the live WebSocket runs (``repose`` + ``settle``, then ``redrape_if_off``;
no server). Each sequence drapes the garment in the default pose, then carries it through ``POSES`` random
poses in a row, each from where the last left it.

Checked at every frame (every step of every settle, the afresh drapes' included): positions finite (no NaN),
the largest spring length / natural length (under ``MAX_STRETCH``). Per settle: a hang (not at rest within
the settings' ``max_steps``, or an exception), the deepest coarse point inside the body as it was at each
step (``motion_max_penetration_mm``, target under ``MOTION_PENETRATION_TARGET_MM``), and at its end what the
done of a live pose update says: vertices more than 2 mm inside the body (target 0) and every sleeve and
trouser leg round its limb (``openings_on_limbs``; ``redraped``: the carried garment had one off and was
draped afresh in that pose). Of the deepest point also the body part it was in and why it may be there:
``tight_there``, the settle's done names that part too tight (a garment too small for the pose, its springs at
their limit pulling the cloth in: the exception issue 26 allows at rest), or ``motion_pinched``, the collision
held it in a pinch between two parts pressed into each other.

``tryon bench --only motion --sequences N`` runs each garment's first N sequences (~10 minutes each over the
catalogue) instead of all twenty.

Random poses are uniform over the real ranges (``POSE_RANGES``: every angle of each side on its own, wrists and
arm turn included; an arm asked lower than it can rest is raised by ``build_body``). Quick mode: the T-shirt
and the trousers M, one sequence of three poses.
"""

from __future__ import annotations

import time

import numpy as np

from tryon.bench.common import Context, Section, Table, fmt
from tryon.bench.fit import BODIES
from tryon.bench.scenes import catalogue_entries, prepared
from tryon.bench.stress import MAX_STRETCH

# Sequences per garment and poses per sequence: the twenty of ten (quick: one of three).
SEQUENCES = {"quick": 1, "full": 20}
POSES = {"quick": 3, "full": 10}
QUICK_GARMENTS = ("tshirt-m.obj", "trousers-m.obj")
SEED = 30
# mm: the target for the deepest penetration of any frame of a motion.
MOTION_PENETRATION_TARGET_MM = 10.0


# Body parts that join at a joint and overlap there by construction (the upper arm goes into the torso at the
# shoulder): a vertex of one inside the other is not a crossing. Any other pair does not touch in a real body.
JOINED = {frozenset(p) for p in (("head", "torso"), ("torso", "upper_arm_l"), ("torso", "upper_arm_r"),
                                 ("upper_arm_l", "forearm_l"), ("upper_arm_r", "forearm_r"), ("torso", "thigh_l"),
                                 ("torso", "thigh_r"), ("thigh_l", "shin_l"), ("thigh_r", "shin_r"),
                                 ("thigh_l", "thigh_r"))}
# m: a part's vertex deeper than this inside a part it does not join makes the pose's body cross itself (the
# metrics' penetration tolerance).
CROSSING_TOLERANCE = 0.002


def body_crossing_mm(body) -> float:
    """How far the body of a pose goes through itself, mm: the deepest vertex of any part inside a part it does
    not join (``JOINED``; a forearm through the torso, the two forearms through each other), 0 when none is
    deeper than ``CROSSING_TOLERANCE``. The full ranges allow such poses (arms swung forwards, turned in and
    bent: the forearms cross in front of the chest); no cloth can lie between the two there."""
    from tryon.sim.collision.collider import BodyCollider

    collider = BodyCollider(body, 0.0)
    part = body.vertex_part
    deepest = 0.0
    for k, name in enumerate(body.parts):
        others = np.array([j for j, other in enumerate(body.parts)
                           if j != k and frozenset((name, other)) not in JOINED], dtype=np.int64)
        depth = collider.depth(body.vertices[part == k], others, offset=False)
        deepest = max(deepest, float(depth.max(initial=0.0)))
    return 1000.0 * deepest if deepest > CROSSING_TOLERANCE else 0.0


def random_pose(rng: np.random.Generator):
    """A ``Pose`` with every angle uniform over its range (``POSE_RANGES``), to 0.1 degree."""
    from tryon.body.params import POSE_RANGES, Pose

    return Pose(**{k: round(float(rng.uniform(lo, hi)), 1) for k, (lo, hi) in POSE_RANGES.items()})


class FrameCheck:
    """An ``on_frame`` callback that watches every frame of a drape of ``model``: whether every position was
    finite, and the largest spring length / natural length seen (``worst``); ``reset`` starts a new settle.
    While it ``watch``es a re-posed drape, also the body part that drape's deepest point was in when ``settle``
    last found a deeper one (``deepest_part``; None while nothing went in), and whether the collision held that
    point in a pinch between two parts then (``deepest_pinched``)."""

    def __init__(self, model):
        self.springs = np.ascontiguousarray(model.springs, dtype=np.int64)
        self.rest = np.asarray(model.rest, dtype=np.float64)
        self.reset()

    def reset(self) -> None:
        self.finite, self.worst, self.frames = True, 0.0, 0
        self.watch(None)

    def watch(self, drape) -> None:
        """Track where ``drape`` (being settled; None: none) goes deepest into the body, from now on."""
        self.drape, self.depth_seen, self.deepest_part, self.deepest_pinched = drape, 0.0, None, False

    def __call__(self, step: int, x: np.ndarray) -> bool:
        from tryon.sim.constraints import spring_lengths

        self.frames += 1
        if not np.isfinite(x).all():
            self.finite = False
            return True
        self.worst = max(self.worst, float((spring_lengths(x, self.springs) / self.rest).max()))
        d = self.drape
        if d is not None and d.state.x is x and d.state.motion_depth > self.depth_seen:
            self.depth_seen = d.state.motion_depth
            i, self.deepest_part = deepest_point(d.control.collider, x)
            self.deepest_pinched = bool(d.state.held[i])
        return True


def deepest_point(collider, x: np.ndarray) -> tuple[int, str]:
    """The deepest of the points ``x`` (k, 3) m inside the body (the body as ``collider`` has it now): its index
    and the name of the body part it is deepest in."""
    parts = collider.body.parts
    every = np.arange(len(parts), dtype=np.int64)
    i = int(collider.depth(x, every, offset=False).argmax())
    depths = [float(collider.depth(x[i:i + 1], every[k:k + 1], offset=False)[0]) for k in range(len(parts))]
    return i, parts[int(np.argmax(depths))]


def too_tight_there(part: str | None, too_tight: dict) -> bool:
    """Whether a settle's ``too_tight`` places (``metrics.too_tight_places``: limb parts by name, the torso by
    band) name the body part ``part``: the garment is too small for the pose where its cloth went in."""
    return part is not None and any(place.split(" ")[0] == part for place in too_tight)


def run_sequence(model, measurements, poses: list, settings=None) -> list[dict]:
    """The garment ``model`` draped on the body of ``measurements`` (a ``Measurements``) in the default pose,
    then re-posed to each of ``poses`` (``Pose``) in turn as a live session does (``repose``, ``settle``,
    ``redrape_if_off``); one record per pose (see the module doc). A settle that raises ends the sequence
    (its record has ``error``; the poses after it are not run)."""
    from tryon.body.build import build_body
    from tryon.body.params import Pose
    from tryon.sim.repose import redrape_if_off, repose
    from tryon.sim.run import settle
    from tryon.sim.settings import SimSettings
    from tryon.sim.start import start

    settings = settings or SimSettings()
    check = FrameCheck(model)
    d = start(build_body(measurements, Pose()), model, settings)
    settle(d)
    records = []
    for i, pose in enumerate(poses):
        check.reset()
        t0 = time.perf_counter()
        rec = {"pose_index": i + 1, "angles": pose.as_dict(), "error": None}
        diverged = False
        try:
            d = repose(d, build_body(measurements, pose))
            rec["transition_steps"] = int(d.control.arms.steps)
            check.watch(d)
            result, _ = settle(d, check)
            m = result.metrics
            rec.update(steps=m["steps"], rest=bool(m["rest_reached"]),
                       motion_mm=float(m["motion_max_penetration_mm"]), carried_on_limbs=m["openings_on_limbs"],
                       motion_part=check.deepest_part, motion_pinched=check.deepest_pinched,
                       too_tight=dict(m["too_tight"]))
            rec["tight_there"] = too_tight_there(rec["motion_part"], rec["too_tight"])
            check.watch(None)  # an afresh drape's frames (below) are not a motion
            d, result, redraped = redrape_if_off(d, result, check)
            m = result.metrics
            rec.update(redraped=redraped, penetrating=int(m["penetrating_vertices"]),
                       max_penetration_mm=float(m["max_penetration_mm"]), on_limbs=m["openings_on_limbs"],
                       off_limbs=[o["opening"] for o in m["limb_openings"] if not o["ok"]])
        except Exception as exc:  # noqa: BLE001 - a settle that raises is what the stress counts
            rec["error"] = f"{type(exc).__name__}: {exc}"
            diverged = isinstance(exc, FloatingPointError)  # the step's own NaN guard
        rec.update(finite=check.finite and not diverged, max_stretch=check.worst,
                   frames=check.frames, wall_s=time.perf_counter() - t0)
        rec["hang"] = rec["error"] is not None or not rec.get("rest", False)
        rec["ok"] = (rec["finite"] and rec["max_stretch"] < MAX_STRETCH and not rec["hang"]
                     and rec["motion_mm"] < MOTION_PENETRATION_TARGET_MM and rec["penetrating"] == 0
                     and rec["on_limbs"] is not False) if rec["error"] is None else False
        records.append(rec)
        if rec["error"] is not None:
            break
    return records


def motion_stress(models: list, sequences: int, poses: int, seed: int = SEED, measurements=None,
                  log=None, crossing: bool = True) -> dict:
    """``sequences`` random sequences of ``poses`` poses (seeded: the same poses for every garment) on each of
    ``models`` (``run_sequence``); the summary (per garment and in all) and every pose's record, with how far
    the pose's body goes through itself (``body_crossing_mm``; ``crossing=False``: not measured, 0)."""
    from tryon.body.params import Measurements

    measurements = measurements or Measurements(**BODIES["medium"])
    from tryon.body.build import build_body

    rng = np.random.default_rng(seed)
    plans = [[random_pose(rng) for _ in range(poses)] for _ in range(sequences)]
    crossing = [[body_crossing_mm(build_body(measurements, pose)) if crossing else 0.0 for pose in plan]
                for plan in plans]
    records = []
    # sequence after sequence, every garment in each: a run stopped early has seen every garment alike
    for s, plan in enumerate(plans):
        for model in models:
            mine = [{"garment": model.meta.name, "sequence": s + 1, **rec,
                     "body_crossing_mm": crossing[s][rec["pose_index"] - 1]}
                    for rec in run_sequence(model, measurements, plan)]
            records += mine
            if log is not None:
                log(f"  motion {model.meta.name} sequence {s + 1}: {sum(r['ok'] for r in mine)}/{len(mine)} ok, "
                    f"deepest {fmt(max((r.get('motion_mm', 0.0) for r in mine), default=0.0))} mm, "
                    f"{sum(r['wall_s'] for r in mine):.1f} s"
                    + "".join(f"; pose {r['pose_index']} ({_angles(r['angles'])}"
                              + (f", body crossing {fmt(r['body_crossing_mm'])} mm" if r["body_crossing_mm"] else "")
                              + f"): {_failure(r)}"
                              for r in mine if not r["ok"]))
    return {"sequences": sequences, "poses": poses, "seed": seed, "garments": summarise(records),
            "all": summarise(records)["all"], "records": records,
            "crossing_poses": sum(c > 0 for plan in crossing for c in plan)}


def summarise(records: list[dict]) -> dict:
    """Per garment (and ``all``): settles, NaN-free, worst stretch, hangs, errors, deepest motion penetration,
    settles over the motion target, settles ending with vertices inside the body, off a limb after the carry
    and at the end, draped afresh, ok."""
    groups = {}
    for r in records:
        groups.setdefault(r["garment"], []).append(r)
    groups["all"] = records
    out = {}
    for name, rs in groups.items():
        done = [r for r in rs if r["error"] is None]
        out[name] = {
            "settles": len(rs), "never_nan": all(r["finite"] for r in rs),
            "max_stretch": max((r["max_stretch"] for r in rs), default=0.0),
            "hangs": sum(r["hang"] for r in rs), "errors": sum(r["error"] is not None for r in rs),
            "motion_max_penetration_mm": max((r["motion_mm"] for r in done), default=0.0),
            "motion_median_mm": float(np.median([r["motion_mm"] for r in done])) if done else 0.0,
            "over_motion_target": sum(r["motion_mm"] >= MOTION_PENETRATION_TARGET_MM for r in done),
            "over_motion_target_tight": sum(r["motion_mm"] >= MOTION_PENETRATION_TARGET_MM and r["tight_there"]
                                            for r in done),
            "over_motion_target_pinched": sum(r["motion_mm"] >= MOTION_PENETRATION_TARGET_MM and r["motion_pinched"]
                                              and not r["tight_there"] for r in done),
            "ending_inside": sum(r["penetrating"] > 0 for r in done),
            "carried_off_limbs": sum(r["carried_on_limbs"] is False for r in done),
            "off_limbs": sum(r["on_limbs"] is False for r in done),
            "redraped": sum(r["redraped"] for r in done), "ok": sum(r["ok"] for r in rs),
            "wall_s": sum(r["wall_s"] for r in rs),
        }
    return out


def _failure(r: dict) -> str:
    """What a pose's record misses, in words."""
    if r["error"] is not None:
        return r["error"]
    out = []
    if not r["finite"]:
        out.append("NaN")
    if r["max_stretch"] >= MAX_STRETCH:
        out.append(f"stretch {fmt(r['max_stretch'])}x")
    if r["hang"]:
        out.append(f"not at rest in {r['steps']} steps")
    if r["motion_mm"] >= MOTION_PENETRATION_TARGET_MM:
        out.append(f"motion {fmt(r['motion_mm'])} mm in {r['motion_part']}"
                   + (" (too tight there)" if r["tight_there"] else " (pinched)" if r["motion_pinched"] else ""))
    if r["penetrating"]:
        out.append(f"{r['penetrating']} vertices inside at rest ({fmt(r['max_penetration_mm'])} mm)")
    if r["on_limbs"] is False:
        out.append("off: " + ", ".join(r["off_limbs"]))
    return "; ".join(out)


def _angles(a: dict) -> str:
    """A pose's angles in a table cell: left/right per joint."""
    names = {"arm_angle": "arm", "arm_forward": "fwd", "arm_rotation": "rot", "elbow_bend": "elbow",
             "wrist_bend": "wrist", "leg_spread": "leg"}
    return " ".join(f"{short} {a[f'{k}_left']:g}/{a[f'{k}_right']:g}" for k, short in names.items())


def run(ctx: Context, sec: Section) -> None:
    mode = "quick" if ctx.quick else "full"
    entries = catalogue_entries()
    if ctx.quick:
        entries = [e for e in entries if e["file"] in QUICK_GARMENTS]
    models = [prepared(ctx, e)[0] for e in entries]
    sequences = ctx.sequences or SEQUENCES[mode]
    summary = motion_stress(models, sequences, POSES[mode], log=ctx.log)
    # every settle's record for the ones missing a target; the others are in the per-garment figures
    sec.data = {"mode": mode if ctx.sequences is None else f"{mode}, {sequences} sequences", "body": BODIES["medium"],
                **{k: v for k, v in summary.items() if k != "records"},
                "failures": [r for r in summary["records"] if not r["ok"]]}
    rows = []
    for name, g in summary["garments"].items():
        rows.append([name, g["settles"], fmt(g["never_nan"]), fmt(g["max_stretch"]), g["hangs"],
                     fmt(g["motion_max_penetration_mm"]), fmt(g["motion_median_mm"]), g["over_motion_target"],
                     g["over_motion_target_tight"], g["over_motion_target_pinched"], g["ending_inside"],
                     g["carried_off_limbs"], g["off_limbs"], g["ok"], fmt(g["wall_s"])])
    sec.tables.append(Table(
        f"Random pose sequences ({sequences} of {POSES[mode]} poses per garment, seed {SEED}, medium body)",
        ["garment", "settles", "never NaN", "max stretch (x)", "hangs", "motion penetration max (mm)",
         "median (mm)", f"over {MOTION_PENETRATION_TARGET_MM:g} mm", "of them too tight there", "pinched",
         "ending inside", "off a limb carried", "off a limb at the end", "ok", "seconds"], rows,
        note=("each sequence: the garment draped in the default pose, then carried through random poses (every "
              "angle of each side uniform over its range) as a live session does (repose, settle, draped afresh "
              "when a sleeve or leg came off and that puts it on). Max stretch: largest spring length / natural "
              f"length of any frame (limit {MAX_STRETCH:g}); hangs: not at rest within the settings' max steps, or "
              "raised; motion penetration: the deepest coarse point inside the body as it was at that step, over "
              "every step of a settle; too tight there: the settle's done names the body part that point was in "
              "among its too_tight places (the garment is too small for that pose there, its springs at their "
              "limit pull the cloth in); pinched: otherwise, the collision held that point where it was, between "
              "two body parts pressed into each other (an arm lowered against the torso), with no place outside "
              "both nearby; ending inside: settles ending with a vertex more than 2 mm inside; off a limb carried: "
              "a sleeve or leg off its limb after the carry (then draped afresh), at the end: still off; ok: every "
              "check met.")))
    failures = [r for r in summary["records"] if not r["ok"]]
    if failures:
        sec.tables.append(Table(
            f"Settles missing a target ({len(failures)}; first 40)",
            ["garment", "sequence", "pose", "angles (left/right, degrees)", "body crossing (mm)", "transition steps",
             "what"],
            [[r["garment"], r["sequence"], r["pose_index"], _angles(r["angles"]), fmt(r["body_crossing_mm"]),
              r.get("transition_steps", "-"), _failure(r)] for r in failures[:40]],
            note=("body crossing: how far the pose's body goes through itself (a limb inside a part it does not "
                  "join, e.g. a forearm in the torso); cloth cannot lie between the two there. "
                  f"{summary['crossing_poses']} of the {sequences * POSES[mode]} poses cross.")))
    a = summary["all"]
    sec.headline.append(
        f"motion: {a['settles']} re-poses ({len(models)} garments x {sequences} random sequences of "
        f"{POSES[mode]} poses), {'no NaN' if a['never_nan'] else 'NaN seen'}, max stretch {fmt(a['max_stretch'])}x "
        f"(limit {MAX_STRETCH:g}), hangs {a['hangs']}, deepest motion penetration {fmt(a['motion_max_penetration_mm'])}"
        f" mm (median {fmt(a['motion_median_mm'])}; over {MOTION_PENETRATION_TARGET_MM:g} mm in "
        f"{a['over_motion_target']}: {a['over_motion_target_tight']} where the garment is too tight for the pose, "
        f"{a['over_motion_target_pinched']} pinched between two parts), ending inside {a['ending_inside']}, "
        f"off a limb at the end {a['off_limbs']} "
        f"(draped afresh {a['redraped']}), every check met {a['ok']}/{a['settles']}; "
        f"{summary['crossing_poses']} of the {sequences * POSES[mode]} poses put a limb through the body")
