"""Whether each sleeve and trouser leg of a drape ends around its own arm or leg (issue 5's target
"sleeves around arms", and the same for legs): a metric of every drape, so a sleeve left across the torso,
a hand through the side of a cuff too small for it, or a shirt slid off the shoulders is reported, not only
seen.

The openings that should end around a limb are found on the aligned garment (``limb_openings``): every
boundary loop of the coarse mesh lying on one side of the body's centre line (sleeve cuffs, armholes,
trouser leg hems; a neck, waist or hem opening runs round the centre line). At the end of the drape an
opening is around a limb part (upper arm or forearm with the hand, thigh or shin with the foot) when, seen
along the part's axis from the centre of the part's cross-section there, its points leave no angular gap of
``MAX_GAP_DEG`` or more, its middle lies along the part and within ``MAX_RADIUS`` of it. An opening around
no part but beyond ``END_FRACTION`` of the limb's length hangs past its end (a sleeve longer than the arm):
the sleeve is around the arm all the same. On the 90 catalogue drapes (``tryon bench --only fit``) every
opening of a garment of the body's size or larger ends around its limb.
"""

from __future__ import annotations

import numpy as np

from tryon.body.types import Body
from tryon.sim.align import body_landmarks, boundary_loops

# The parts of each limb, from the body's trunk out.
LIMB_PARTS = {"arm": ("upper_arm", "forearm"), "leg": ("thigh", "shin")}
SIDES = (("left", "l", 1.0), ("right", "r", -1.0))
# An opening surrounds an axis when seen along it no gap between its points spans this much: a cuff or hem
# ring covers 360 degrees less its point spacing; one lying beside the limb spans under 180.
MAX_GAP_DEG = 120.0
# m: farther than this from the axis, on average, an opening is not around that limb (a skirt-wide ring).
MAX_RADIUS = 0.2
# Along the axis, as a fraction of the part's length from its joint: a cuff may hang over the hand and a
# trouser hem over the foot, past the forearm's or shin's end.
ALONG = (-0.2, 1.3)
# m: half the thickness of the slice of a limb part whose centre an opening is seen around.
SECTION_HALF = 0.015
# Of the last part's length (forearm with the hand, shin with the foot): an opening not around the part and
# beyond this hangs past the limb's end (a sleeve longer than the arm, its cuff bunched over the fingers).
END_FRACTION = 0.9
# At least this fraction of an opening's points lie on its side of the centre line.
OPENING_SHARE = 0.8


def _distance_to_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    t = float(np.clip((p - a) @ (b - a) / max((b - a) @ (b - a), 1e-12), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * (b - a))))


def limb_openings(x: np.ndarray, faces: np.ndarray, body: Body) -> list[tuple[str, str, np.ndarray]]:
    """The openings of the aligned garment (coarse points x (k, 3) m, faces (f, 3)) that should end around a
    limb: (side "left" | "right", limb "arm" | "leg", point ids (q,) int64) for every opening lying
    (``OPENING_SHARE`` of its points) on one side of the body's centre line, the limb being the one whose
    axis its centre is nearest: sleeve cuffs and armholes, trouser leg hems. A neck, waist or hem opening
    runs round the centre line and is none of them."""
    lm = body_landmarks(body)
    out = []
    for loop in boundary_loops(faces, len(x)):
        centre = x[loop].mean(axis=0)
        for side, suffix, sign in SIDES:
            if ((x[loop, 0] - lm.center_x) * sign > 0).mean() < OPENING_SHARE:
                continue
            nearest = {}
            for limb, parts in LIMB_PARTS.items():
                axes = [body.part_axes[body.parts.index(f"{p}_{suffix}")] for p in parts
                        if f"{p}_{suffix}" in body.parts]
                if axes:
                    nearest[limb] = min(_distance_to_segment(centre, a, b) for a, b in axes)
            if nearest:
                out.append((side, min(nearest, key=nearest.get), loop))
    return out


def around_part(points: np.ndarray, a: np.ndarray, b: np.ndarray, surface: np.ndarray) -> bool:
    """Whether the points (q, 3) m surround the limb part whose axis runs from a to b (3,) m and whose
    surface vertices are ``surface`` (p, 3) m (see the module doc). Seen along the axis, around the centre
    of the part's cross-section where the points are: a joint-to-joint axis may run a centimetre or two off
    the centre of a wrist, and a cuff tight around it would seem to lie to one side of it."""
    axis = b - a
    length = float(np.linalg.norm(axis))
    if len(points) < 3 or length == 0.0:
        return False
    axis = axis / length
    along = (points - a) @ axis
    t = float(np.median(along))
    # the slice of the part nearest the opening (an armhole lies round the shoulder joint, where the
    # upper arm begins)
    t_slice = min(max(t, SECTION_HALF), length - SECTION_HALF)
    section = np.abs((surface - a) @ axis - t_slice) < SECTION_HALF
    if not ALONG[0] <= t / length <= ALONG[1] or section.sum() < 3:
        return False
    rel = points - surface[section].mean(axis=0)
    radial = rel - (rel @ axis)[:, None] * axis
    if float(np.linalg.norm(radial, axis=1).mean()) > MAX_RADIUS:
        return False
    u = np.cross(axis, [0.0, 0.0, 1.0])
    if np.linalg.norm(u) < 1e-6:  # an axis along z
        u = np.cross(axis, [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(axis, u)
    angles = np.sort(np.arctan2(radial @ w, radial @ u))
    gap = max(float(np.diff(angles).max(initial=0.0)), float(angles[0] + 2 * np.pi - angles[-1]))
    return gap < np.radians(MAX_GAP_DEG)


def openings_on_limbs(x: np.ndarray, body: Body, openings: list[tuple[str, str, np.ndarray]]) -> list[dict]:
    """Where each opening (``limb_openings``) ended, for the draped coarse points x (k, 3) m:
    {"opening": "left arm" ..., "around": the part of that limb its points surround ("upper_arm_l" ...;
    the one nearer the trunk if both) or None, "past_end": whether it hangs past the limb's end (a sleeve
    longer than the arm, past the fingertips), "ok": around a part or past the end}."""
    out = []
    for side, limb, loop in openings:
        suffix = dict((s, c) for s, c, _ in SIDES)[side]
        around, past_end = None, False
        for part in LIMB_PARTS[limb]:
            name = f"{part}_{suffix}"
            if name not in body.parts:
                continue
            k = body.parts.index(name)
            a, b = body.part_axes[k]
            surface = body.vertices[np.unique(body.faces[body.face_part == k])]
            if around_part(x[loop], a, b, surface):
                around = name
                break
            # measured on the last part (forearm with hand, shin with foot): its axis ends at the limb's end
            past_end = bool(np.median((x[loop] - a) @ (b - a)) > END_FRACTION * ((b - a) @ (b - a)))
        out.append({"opening": f"{side} {limb}", "around": around, "past_end": past_end and around is None,
                    "ok": around is not None or past_end})
    return out
