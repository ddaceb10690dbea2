"""Putting the garment on the body before the simulation starts (paper section 3.1).

1. Global alignment: centre the garment on the torso in x and z, and translate it vertically so that a
   top's (or dress's) shoulder line sits on the body's shoulders, or a bottom's waistband at the body's
   waist level. A garment whose units were guessed at ingestion is also scaled so that its girth at the
   chest (hips for bottoms) is about 1.15 x the body's (a garment in the right units is never rescaled:
   its size is the point of trying it on).
2. Local alignment (the paper's construction): a = the garment's rear-most point (smallest z) on the
   torso, b = the body point nearest to a, c = the garment's highest point near the centre line (the
   collar for a top, the waistband for a bottom); the garment turns about the X axis through c by the
   angle between (a - c) and (b - c), so its back follows the body's back. Limited to +-15 degrees.
3. Sleeve directions: the angle between each sleeve and the vertical (in the body's frontal plane) is
   measured, so the simulation can pose the arms along the sleeves and bring them back (``ArmPlan``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from tryon.body.types import Body
from tryon.garment.model import GarmentModel

# m: the garment's shoulder line is placed this far above the body's (a few mm of air, so the first
# step does not start in contact; gravity closes the gap at once).
SHOULDER_CLEARANCE = 0.01
# Target girth ratio garment / body when a garment's units were guessed (a loose but not baggy fit).
GUESSED_UNITS_EASE = 1.15
# Largest local-alignment turn about X, radians: the construction is a correction, not a re-posing.
MAX_LOCAL_TURN = np.radians(15.0)
# Smallest difference between sleeve and arm angles worth posing the arms for, radians.
MIN_ARM_TURN = np.radians(6.0)


@dataclass(frozen=True)
class BodyLandmarks:
    """Heights (m, y) and positions of the body used for alignment."""

    center_x: float
    shoulder_y: float  # top of the shoulders, between neck and arm
    shoulder_half: float  # half the distance between the shoulder joints, m
    chest_y: float
    waist_y: float
    hips_y: float
    shoulder_l: np.ndarray  # (3,) left shoulder joint (+x)
    shoulder_r: np.ndarray


@dataclass(frozen=True)
class ArmPlan:
    """Arm abduction turns (radians, about the body's z axis through each shoulder joint) that put each
    arm along its sleeve; 0 when no turn is needed. Left arm is towards +x."""

    left: float
    right: float


def _part(body: Body, name: str) -> int | None:
    return body.parts.index(name) if name in body.parts else None


def body_landmarks(body: Body) -> BodyLandmarks:
    """Landmarks from the body's parts, axes and girth levels (estimated from the torso when absent)."""
    kt = _part(body, "torso")
    torso_axis = body.part_axes[kt]
    y0, y1 = sorted((float(torso_axis[0, 1]), float(torso_axis[1, 1])))
    length = y1 - y0
    cx = float(torso_axis[:, 0].mean())
    kl, kr = _part(body, "upper_arm_l"), _part(body, "upper_arm_r")
    sh_l = body.part_axes[kl, 0].copy()
    sh_r = body.part_axes[kr, 0].copy()
    if sh_l[0] < sh_r[0]:
        sh_l, sh_r = sh_r, sh_l
    half = 0.5 * abs(sh_l[0] - sh_r[0])
    face_in = np.isin(body.face_part, [kt, kl, kr])
    verts = body.vertices[np.unique(body.faces[face_in])]
    dx = np.abs(verts[:, 0] - cx)
    band = (dx > 0.5 * half) & (dx < 0.9 * half)
    shoulder_y = float(verts[band, 1].max()) if band.any() else float(sh_l[1])
    levels = body.levels or {}
    return BodyLandmarks(
        center_x=cx,
        shoulder_y=shoulder_y,
        shoulder_half=half,
        chest_y=float(levels.get("chest", y0 + 0.72 * length)),
        waist_y=float(levels.get("waist", y0 + 0.40 * length)),
        hips_y=float(levels.get("hips", y0 + 0.15 * length)),
        shoulder_l=sh_l,
        shoulder_r=sh_r,
    )


def _band(points: np.ndarray, y: float, cx: float, half_width: float, dy: float = 0.04) -> np.ndarray:
    sel = (np.abs(points[:, 1] - y) < dy) & (np.abs(points[:, 0] - cx) < half_width)
    return points[sel]


def _girth(points: np.ndarray) -> float:
    """Perimeter (m) of the convex hull of the points' (x, z) projection (a tape-measure girth)."""
    if len(points) < 3:
        return 0.0
    try:
        return float(ConvexHull(points[:, [0, 2]]).area)  # in 2-D, ``area`` is the perimeter
    except QhullError:  # all points on a line: no girth to speak of
        return 0.0


def torso_points(body: Body) -> np.ndarray:
    """(m, 3) vertices of the torso part."""
    kt = _part(body, "torso")
    return body.vertices[np.unique(body.faces[body.face_part == kt])]


def align_garment(body: Body, model: GarmentModel, points: np.ndarray | None = None) -> np.ndarray:
    """Aligned copy (k, 3) of ``points`` (default: the garment's coarse rest positions), see module doc.

    The same rigid transform (plus scale) is what one would apply to the full mesh; we only need it
    for the coarse one, since the full mesh follows the coarse one through the re-attachment.
    """
    x = np.array(model.coarse_vertices if points is None else points, dtype=np.float64)
    lm = body_landmarks(body)
    torso = torso_points(body)
    category = model.meta.category
    top = category in ("top", "dress")
    level = lm.chest_y if top else lm.hips_y

    # --- global: centre x, place vertically, centre z
    x[:, 0] += lm.center_x - 0.5 * (x[:, 0].min() + x[:, 0].max())
    if top:
        dx = np.abs(x[:, 0] - lm.center_x)
        band = (dx > 0.5 * lm.shoulder_half) & (dx < 0.9 * lm.shoulder_half)
        garment_y = x[band, 1].max() if band.sum() >= 3 else x[:, 1].max()
        x[:, 1] += lm.shoulder_y + SHOULDER_CLEARANCE - garment_y
    else:
        x[:, 1] += lm.waist_y - x[:, 1].max()

    body_band = _band(torso, level, lm.center_x, 2.0 * lm.shoulder_half)
    if getattr(model.meta, "units_guessed", False):
        g_band = _band(x, level, lm.center_x, 1.2 * lm.shoulder_half)
        gg, bg = _girth(g_band), _girth(body_band)
        if gg > 0 and bg > 0:
            ratio = gg / bg
            if not 0.95 <= ratio <= 1.6:
                anchor = np.array([lm.center_x, lm.shoulder_y if top else lm.waist_y, x[:, 2].mean()])
                x = anchor + (x - anchor) * (GUESSED_UNITS_EASE / ratio)

    g_band = _band(x, level, lm.center_x, 0.8 * lm.shoulder_half)
    if len(g_band) and len(body_band):
        x[:, 2] += 0.5 * (body_band[:, 2].min() + body_band[:, 2].max()) - 0.5 * (g_band[:, 2].min() + g_band[:, 2].max())

    # --- local: turn about X through the collar / waistband centre (paper 3.1)
    x = local_alignment(x, torso, lm, top)
    return x


def local_alignment(x: np.ndarray, torso: np.ndarray, lm: BodyLandmarks, top: bool) -> np.ndarray:
    """The paper's rotation about X (see module doc); returns the turned copy of ``x`` (k, 3)."""
    cx = lm.center_x
    near_centre = np.abs(x[:, 0] - cx) < 0.25 * lm.shoulder_half
    if near_centre.sum() < 3:
        return x
    c = x[near_centre][np.argmax(x[near_centre, 1])]
    y_lo = lm.waist_y if top else lm.hips_y - 0.1
    y_hi = lm.chest_y if top else lm.waist_y
    region = (np.abs(x[:, 0] - cx) < 0.5 * lm.shoulder_half) & (x[:, 1] > y_lo) & (x[:, 1] < y_hi)
    if region.sum() < 3:
        return x
    a = x[region][np.argmin(x[region, 2])]
    b = torso[np.argmin(np.linalg.norm(torso - a, axis=1))]
    u = (a - c)[1:]
    v = (b - c)[1:]
    if np.linalg.norm(u) < 1e-6 or np.linalg.norm(v) < 1e-6:
        return x
    # signed angle from u to v in the (y, z) plane; a turn about +x maps y -> z
    angle = np.arctan2(u[0] * v[1] - u[1] * v[0], u @ v)
    angle = float(np.clip(angle, -MAX_LOCAL_TURN, MAX_LOCAL_TURN))
    cs, sn = np.cos(angle), np.sin(angle)
    rot = np.array([[1, 0, 0], [0, cs, -sn], [0, sn, cs]])
    return c + (x - c) @ rot.T


def arm_angle(body: Body, side: str) -> float:
    """Abduction of the upper arm (radians): its axis direction's angle from straight down, in x-y."""
    k = _part(body, f"upper_arm_{side}")
    d = body.part_axes[k, 1] - body.part_axes[k, 0]
    return float(np.arctan2(abs(d[0]), -d[1]))


def plan_arms(body: Body, x: np.ndarray, category: str) -> ArmPlan:
    """Turns that put each arm along its sleeve, measured from the aligned garment points (k, 3).

    Sleeve points: garment points beyond 1.4 x the shoulder-joint half-width from the centre (past the
    bodice of a fitted top or dress), above the chest-to-waist mid level; the sleeve direction is from
    the shoulder joint to their centroid.
    No sleeve (bottoms, sleeveless dresses, too few points): no turn.
    """
    if category == "bottom":
        return ArmPlan(0.0, 0.0)
    lm = body_landmarks(body)
    turns = []
    for side, sign, joint in (("l", 1.0, lm.shoulder_l), ("r", -1.0, lm.shoulder_r)):
        rel = (x[:, 0] - lm.center_x) * sign
        sel = (rel > 1.4 * lm.shoulder_half) & (x[:, 1] > 0.5 * (lm.chest_y + lm.waist_y))
        if sel.sum() < 8:
            turns.append(0.0)
            continue
        d = x[sel].mean(axis=0) - joint
        sleeve = float(np.arctan2(abs(d[0]), -d[1]))
        turn = sleeve - arm_angle(body, side)
        turns.append(turn if abs(turn) >= MIN_ARM_TURN else 0.0)
    return ArmPlan(left=turns[0], right=turns[1])
