"""Aiming the arms along the sleeves (paper section 3.1, step 3): the turn of each arm at the shoulder (and, for
a long sleeve bent at the elbow, of the forearm about the elbow) that puts it inside its sleeve as the garment
was modelled (``plan_arms`` -> ``ArmPlan``); the simulation poses the arms so and turns them back to the body's
pose over its first steps (``arms.ArmSchedule``). From the aligned garment points (k, 3) m and the body."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tryon.body.params import POSE_RANGES
from tryon.body.types import Body
from tryon.garment.topology import boundary_loops
from tryon.geometry import rotation
from tryon.sim.landmarks import BodyLandmarks, arm_joints, body_landmarks, part_index, part_points
from tryon.sim.pieces import bottom_mask
from tryon.sim.sleeves import MIN_SLEEVE_POINTS, far_opening, side_opening, sleeve_mask, sleeve_openings

# A sleeve made on arms hanging at the sides (the DiffCloth dress's, whose cuffs hang at the hips) lies within
# the torso's half-width, where no sleeve is looked for: its cuff is an opening on one side centred more
# than this x the upper arm's length from the shoulder joint. On the medium body a sleeveless bodice's
# armhole is centred 0.14-0.3 of it from the joint (the catalogue's sleeveless dresses, the DiffAvatar strap
# dress), a short sleeve's cuff 0.73-0.86 (the catalogue's and DiffAvatar's T-shirts), the DiffCloth dress's 1.18.
HANGING_CUFF = 0.6
# Smallest difference between sleeve and arm angles worth posing the arms for, radians.
MIN_ARM_TURN = np.radians(6.0)
# A sleeve whose cuff the arm would not go through is aimed through its cuff, however small the turn: the hand
# would start outside the cuff, across its rim, and end beside it, out through the side of the sleeve. The arm
# goes through when its line passes the cuff's centre closer than CUFF_MISS x the cuff's mean radius less the
# arm's own half-width there, as the arm starts (the body grown from ``SimSettings.grow_from`` of its size).
# With the arm's line alone (no half-width) the catalogue's long-sleeve S on the medium body and the S and M on
# the large one, 2-6 degrees off, were missed (``tryon bench --only fit``: their shown-mesh strain 1.7 / 6.2 /
# 2.6 -> 0.4 / 0.5 / 0.4 once aimed), and the long-sleeve M on the chart's M body kept its left arm 3.9 cm off
# a cuff of 4.0 cm radius (its right, 4.0 cm off, was aimed): the hand started across the rim and the cuff ended
# folded round the wrist, too tight.
CUFF_MISS = 1.0
# m: the arm's body points within this of the cuff's centre along the arm give its half-width there.
CUFF_SLICE = 0.015
# Smallest bend of a long sleeve at the elbow worth turning the forearm for, radians; a smaller bend is
# followed by the one shoulder turn along the whole sleeve. Measured on the small / medium / large bodies:
# the MakeHuman blouse's sleeves 38-53 degrees, the MakeHuman men's shirt 26-31, the catalogue's long
# sleeves 0-15 (their wide tops pull the upper part's centre off the arm's line). Turning the catalogue's
# 10-15 degree sleeves too changed 5 of its 27 long-sleeve drapes, none for the worse (springs over the
# target: large M 1063 -> 421, large L 672 -> 0; the others stay at 0).
MIN_ELBOW_TURN = np.radians(10.0)
# The upper part of a sleeve, whose centre line the upper arm is turned onto when the sleeve is bent: its
# points between these fractions of the upper arm's length from the shoulder joint.
UPPER_SLEEVE = (0.4, 0.9)
# The upper part's points lie beyond this many torso half-widths: a ring round the upper arm, whose inner
# side is nearer the torso than the sleeve points SLEEVE_REACH finds. At 1.0 the ring's centre lay off the
# arm and the long-sleeves S and L on arms raised to 90 degrees ended with 273 and 496 springs over; at 0.9
# and 0.95 with none.
RING_REACH = 0.95
# A sleeve has a forearm part when its far opening is at least this fraction of the forearm's length
# off the upper arm (beyond the elbow, or beside it when the sleeve is bent; a short sleeve ends round the
# upper arm).
FOREARM_SLEEVE = 0.2
# Largest elbow turn, radians: the elbow's range of flexion (the body's own pose range) and 30 degrees
# more, for a sleeve bent another way than the body's forearm (the catalogue's long-sleeve M, made
# 10 degrees bent, is 129 degrees off a forearm bent 120 degrees).
MAX_ELBOW_TURN = np.radians(POSE_RANGES["elbow_bend_left"][1] + 30.0)


@dataclass(frozen=True)
class ArmPlan:
    """Arm turns (radians) about each shoulder joint that put each arm along its sleeve; 0 when no turn is
    needed. ``left_axis`` / ``right_axis`` (3,) unit: the axis of each turn (right-handed); the default,
    the body's z axis (+z for the left arm, towards +x, and -z for the right), makes the angles plain
    abductions in the frontal plane."""

    left: float
    right: float
    left_axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    right_axis: tuple[float, float, float] = (0.0, 0.0, -1.0)
    # Forearm turns (radians) about each elbow, after the shoulder turn, for a sleeve bent at the elbow;
    # each axis is given in the arm's rest pose (the shoulder turn carries it along with the upper arm).
    left_elbow: float = 0.0
    right_elbow: float = 0.0
    left_elbow_axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    right_elbow_axis: tuple[float, float, float] = (0.0, 0.0, -1.0)
    # The far opening (point ids into the garment's coarse points) of each turned arm's sleeve, if known.
    left_cuff: np.ndarray | None = None
    right_cuff: np.ndarray | None = None


def arm_misses(cuff: np.ndarray, joint: np.ndarray, arm: np.ndarray, half_width: float = 0.0) -> bool:
    """Whether an arm from the shoulder ``joint`` (3,) along the unit direction ``arm`` (3,), ``half_width`` m
    thick on each side of its line where it meets the opening whose points are ``cuff`` (q, 3), misses it: its
    line lies farther from the opening's centre than ``CUFF_MISS`` x the opening's mean radius less
    ``half_width``."""
    centre = cuff.mean(axis=0)
    radius = float(np.linalg.norm(cuff - centre, axis=1).mean())
    rel = centre - joint
    return float(np.linalg.norm(rel - (rel @ arm) * arm)) + half_width > CUFF_MISS * radius


def arm_half_width(body: Body, side: str, joint: np.ndarray, arm: np.ndarray, at: np.ndarray) -> float:
    """How far (m) the arm's surface reaches from its line (from the shoulder ``joint`` (3,) along the unit
    ``arm`` (3,)) level with the point ``at`` (3,): the 90th percentile of the distances of the arm's body
    points within ``CUFF_SLICE`` of that level (the hand's breadth at a cuff over it); 0 past the arm's end or
    on a body without that arm."""
    parts = [k for k in (part_index(body, f"{p}_{side}") for p in ("upper_arm", "forearm")) if k is not None]
    if not parts:
        return 0.0
    points = np.concatenate([part_points(body, k) for k in parts])
    along = (points - joint) @ arm
    level = (np.asarray(at) - joint) @ arm
    near = np.abs(along - level) < CUFF_SLICE
    if not near.any():
        return 0.0
    off = points[near] - joint - np.outer(along[near], arm)
    return float(np.quantile(np.linalg.norm(off, axis=1), 0.9))


def hanging_cuff(body: Body, side: str, x: np.ndarray, lm: BodyLandmarks, sign: float, loops: list[np.ndarray],
                 upper: np.ndarray) -> np.ndarray | None:
    """The cuff (point ids into x (k, 3)) of a sleeve hanging beside the torso on one side (``side`` "l" |
    "r", ``sign`` +1 for the body's left), or None: of the openings of the pieces over the shoulders
    (``upper`` (k,) bool) on that side (``side_opening``), the one farthest below the shoulder joint, if
    its centre is more than ``HANGING_CUFF`` x the upper arm's length from the joint and the arm would miss
    it (``arm_misses``). A sleeveless bodice's armhole is centred near the joint."""
    if part_index(body, f"upper_arm_{side}") is None:
        return None
    joint, elbow, _ = arm_joints(body, side)
    reach = HANGING_CUFF * float(np.linalg.norm(elbow - joint))
    arm = arm_direction(body, side)
    best, best_drop = None, 0.0
    for loop in loops:
        if not upper[loop].all():
            continue
        p = x[loop]
        if not side_opening(p, lm, sign):
            continue
        centre = p.mean(axis=0)
        if np.linalg.norm(centre - joint) < reach or not arm_misses(p, joint, arm):
            continue
        drop = joint[1] - centre[1]
        if drop > best_drop:
            best, best_drop = loop, drop
    return best


def arm_angle(body: Body, side: str) -> float:
    """Abduction of the upper arm (radians): its axis direction's angle from straight down, in x-y."""
    k = part_index(body, f"upper_arm_{side}")
    d = body.part_axes[k, 1] - body.part_axes[k, 0]
    return float(np.arctan2(abs(d[0]), -d[1]))


def plan_arms(body: Body, x: np.ndarray, category: str, faces: np.ndarray | None = None,
              loops: list[np.ndarray] | None = None, piece: np.ndarray | None = None,
              start_scale: float = 1.0) -> ArmPlan:
    """Turns that put each arm along its sleeve, measured from the aligned garment points (k, 3).

    Sleeve points: points of the pieces over the shoulders (``faces`` (f, 3), if given, tells the pieces
    apart; a bottom has no sleeves) beyond ``SLEEVE_REACH`` x the torso half-width from the centre (past the
    bodice of a fitted top or dress), above the chest-to-waist mid level. The sleeve direction is from
    the shoulder joint to their centroid, in 3-D: a sleeve made on a body whose arms hang further forward
    (DiffAvatar's long-sleeve shirt: 9 cm in front of this body's arm at the cuff, with a 5 cm cuff
    radius) is missed by an arm turned only in the frontal plane, which then cuts through the sleeve's
    back and bunches it on the upper arm. The turn is about the axis normal to both the arm (shoulder to
    wrist) and the sleeve direction.

    A sleeve only a few degrees off the arm (under ``MIN_ARM_TURN``) is still turned if the arm would miss
    its cuff (``CUFF_MISS``; the arm ``start_scale`` of its thickness, as the drape starts it): then the arm is
    aimed through the cuff's centre. ``loops``: the boundary loops
    of ``faces`` if known (``GarmentModel.coarse_loops``); ``piece`` (k,): the points'
    ``pieces.piece_labels`` if known.

    A long sleeve bent at the elbow (``bent_sleeve_turns``) is followed in two turns instead: the upper
    arm onto the sleeve's upper part, then the forearm about the elbow onto the sleeve's far opening; a
    straight arm turned at the shoulder only cuts through such a sleeve below the elbow.
    A sleeve made on arms hanging at the sides lies within the torso's width, with no points out there: the
    arm is aimed through its cuff (``hanging_cuff``), an opening on that side far below the shoulder joint.
    No sleeve (bottoms, too few points, or no opening out there: a sleeveless bodice wider than the body's
    shoulders, whose armhole is centred near the joint): no turn.
    """
    if category == "bottom":
        return ArmPlan(0.0, 0.0)
    lm = body_landmarks(body)
    upper = np.ones(len(x), dtype=np.bool_) if faces is None else ~bottom_mask(x, faces, category, piece)
    if loops is None:
        loops = boundary_loops(faces, len(x)) if faces is not None else []
    out, cuffs = {}, {}
    for side, sign, joint in (("l", 1.0, lm.shoulder_l), ("r", -1.0, lm.shoulder_r)):
        sel = upper & sleeve_mask(x, lm, sign)
        default_axis = (0.0, 0.0, sign)
        out[side] = (0.0, default_axis, 0.0, default_axis)
        cuffs[side] = None
        ends = sleeve_openings(x, lm, sign, loops, upper) if sel.sum() >= MIN_SLEEVE_POINTS else []
        if not ends and (faces is not None or sel.sum() < MIN_SLEEVE_POINTS):
            # no sleeve reaching out with an opening out there. Maybe the side of a bodice wider than the
            # body's shoulders (a dress two sizes too big), not a sleeve: turning the arm onto it would carry
            # the armhole down the arm. But a sleeve made on arms at the sides hangs beside the torso: the
            # arm is aimed through its cuff
            hanging = hanging_cuff(body, side, x, lm, sign, loops, upper)
            if hanging is not None:
                cuffs[side] = hanging
                turn, axis = _turn_between(arm_direction(body, side), x[hanging].mean(axis=0) - joint)
                out[side] = (turn, axis, 0.0, default_axis)
            continue
        if ends:
            cuffs[side] = far_opening(x, ends, joint)
        bent = bent_sleeve_turns(body, side, x, upper & sleeve_mask(x, lm, sign, RING_REACH), cuffs[side])
        if bent is not None:
            out[side] = bent
            continue
        sleeve = x[sel].mean(axis=0) - joint
        arm = arm_direction(body, side)
        if ends and part_index(body, f"forearm_{side}") is not None:
            # a short sleeve (its cuff round the upper arm) is along the upper arm, however bent the elbow
            _, elbow, _ = arm_joints(body, side)
            if (x[cuffs[side]].mean(axis=0) - joint) @ (elbow - joint) < (elbow - joint) @ (elbow - joint):
                arm = (elbow - joint) / np.linalg.norm(elbow - joint)
        turn, axis = _turn_between(arm, sleeve)
        misses_cuff = False
        if ends:
            # the arm must go through the cuff: aim at the centre of the far opening if the arm misses it
            far = x[cuffs[side]]
            width = start_scale * arm_half_width(body, side, joint, arm, far.mean(axis=0))
            misses_cuff = arm_misses(far, joint, arm, width)
            if misses_cuff:
                turn, axis = _turn_between(arm, far.mean(axis=0) - joint)
        if misses_cuff or turn >= MIN_ARM_TURN:
            out[side] = (turn, axis, 0.0, default_axis)
    (lt, la, le, lea), (rt, ra, re, rea) = out["l"], out["r"]
    return ArmPlan(left=lt, right=rt, left_axis=la, right_axis=ra, left_elbow=le, right_elbow=re,
                   left_elbow_axis=lea, right_elbow_axis=rea, left_cuff=cuffs["l"], right_cuff=cuffs["r"])


def _turn_between(a: np.ndarray, b: np.ndarray) -> tuple[float, tuple[float, float, float]]:
    """Angle (radians) and unit axis of the shortest turn taking direction ``a`` (3,) to ``b`` (3,)."""
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    normal = np.cross(a, b)
    length = float(np.linalg.norm(normal))
    if length < 1e-9:
        return 0.0, (0.0, 0.0, 1.0)
    return float(np.arctan2(length, a @ b)), tuple(float(c) for c in normal / length)


def bent_sleeve_turns(body: Body, side: str, x: np.ndarray, sleeve: np.ndarray, cuff_ids: np.ndarray | None
                      ) -> tuple[float, tuple, float, tuple] | None:
    """(shoulder turn, its axis, elbow turn, its axis in the arm's rest pose) that put the upper arm along
    the sleeve's upper part (the centroid of its points ``UPPER_SLEEVE`` of the upper arm's length from
    the shoulder joint) and then the forearm, turned about the elbow, through the centre of the sleeve's
    far opening ``cuff_ids`` (point ids; ``far_opening``, None if the sleeve has no opening); ``sleeve``
    (k,) bool marks the sleeve's points. None when the sleeve is not a long sleeve bent by
    ``MIN_ELBOW_TURN`` to ``MAX_ELBOW_TURN`` (then one shoulder turn along the whole sleeve is enough), or
    the body has no forearm."""
    if part_index(body, f"forearm_{side}") is None:
        return None
    joint, elbow, wrist = arm_joints(body, side)
    upper_len = float(np.linalg.norm(elbow - joint))
    fore_len = float(np.linalg.norm(wrist - elbow))
    if cuff_ids is None:
        return None
    cuff = x[cuff_ids].mean(axis=0)
    r = np.linalg.norm(x - joint, axis=1)
    ring = sleeve & (r > UPPER_SLEEVE[0] * upper_len) & (r < UPPER_SLEEVE[1] * upper_len)
    if ring.sum() < MIN_SLEEVE_POINTS:
        return None
    turn, axis = _turn_between(elbow - joint, x[ring].mean(axis=0) - joint)
    rot = rotation(np.asarray(axis), turn)
    posed_elbow = joint + rot @ (elbow - joint)
    if _off_segment(cuff, joint, posed_elbow) < FOREARM_SLEEVE * fore_len:
        return None
    bend, bend_axis = _turn_between(rot @ (wrist - elbow), cuff - posed_elbow)
    if not MIN_ELBOW_TURN <= bend <= MAX_ELBOW_TURN:
        return None
    rest_axis = tuple(float(c) for c in rot.T @ np.asarray(bend_axis))
    return turn, axis, bend, rest_axis


def _off_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Distance (m) of the point p (3,) from the segment a-b (3,) each."""
    t = float(np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0))
    return float(np.linalg.norm(p - a - t * (b - a)))


def arm_direction(body: Body, side: str) -> np.ndarray:
    """(3,) unit direction from the shoulder joint to the wrist (the end of the forearm's axis, else of
    the upper arm's)."""
    k = part_index(body, f"upper_arm_{side}")
    kf = part_index(body, f"forearm_{side}")
    end = body.part_axes[kf, 1] if kf is not None else body.part_axes[k, 1]
    d = end - body.part_axes[k, 0]
    return d / np.linalg.norm(d)
