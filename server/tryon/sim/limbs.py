"""Whether each sleeve and trouser leg of a drape ends around its own arm or leg (issue 5's target
"sleeves around arms", and the same for legs): a metric of every drape, so a sleeve left across the torso,
a hand through the side of a cuff too small for it, or a shirt slid off the shoulders is reported, not only
seen.

The openings that should end around a limb are found on the aligned garment (``limb_openings``): the
boundary loops of the coarse mesh lying on one side of the body's centre line: on a piece over the
shoulders, for an arm (sleeve cuffs, armholes); on a piece hanging from the waist, for a leg if there is one
on each side (trouser leg hems); a neck, waist or hem opening runs round the centre line. At the end of the
drape an opening is around a limb part (upper arm or forearm with the hand, thigh or shin with the foot)
when, seen along the part's axis, it winds once round the centre of the part's cross-section there, its
middle lying along the part and within ``MAX_RADIUS`` of it. An opening around no part but hanging within
``MAX_RADIUS`` of the limb's end, beyond ``END_FRACTION`` of its last part, is past its end (a sleeve
longer than the arm): the sleeve is around the arm all the same. An opening whose coarse ring is around no
part is judged again on the shown mesh's ring (``openings_on_shown_limbs``): a tight hem of a few coarse
points can chord across a limb that the shown hem goes round. On the 90 catalogue drapes
(``tryon bench --only fit``) every opening ends around its limb (on the coarse ring).
"""

from __future__ import annotations

import numpy as np

from tryon.body.types import Body
from tryon.garment.topology import boundary_loops
from tryon.sim.landmarks import body_landmarks, part_points
from tryon.sim.sleeves import side_opening
from tryon.sim.pieces import bottom_mask

# The parts of each limb, from the body's trunk out.
LIMB_PARTS = {"arm": ("upper_arm", "forearm"), "leg": ("thigh", "shin")}
SIDES = (("left", "l", 1.0), ("right", "r", -1.0))
# m: farther than this from the axis, on average, an opening is not around that limb (a skirt-wide ring).
MAX_RADIUS = 0.2
# Along the axis, as a fraction of the part's length from its joint: a cuff may hang over the hand and a
# trouser hem over the foot, past the forearm's or shin's end.
ALONG = (-0.2, 1.3)
# m: half the thickness of the slice of a limb part whose centre an opening is seen around.
SECTION_HALF = 0.015
# Of the upper arm's (thigh's) length from its joint: an opening whose middle lies nearer the joint than this
# is round the limb's root (an armhole): seen along the raised arm's axis it can be a thin sliver, the arm
# leaving it across its plane, and the winding test fails; then whether the limb passes through it decides
# (``through_root``).
ROOT_REACH = 0.3
# Of the last part's length (forearm with the hand, shin with the foot): an opening not around the part,
# beyond this and within MAX_RADIUS of the end hangs past the limb's end (a sleeve longer than the arm, its
# cuff bunched over the fingers).
END_FRACTION = 0.9


def limb_openings(x: np.ndarray, faces: np.ndarray, body: Body, category: str,
                  loops: list[np.ndarray] | None = None,
                  piece: np.ndarray | None = None) -> list[tuple[str, str, np.ndarray]]:
    """The openings of the aligned garment (coarse points x (k, 3) m, faces (f, 3), ``category`` top |
    bottom | dress) that should end around a limb: (side "left" | "right", limb "arm" | "leg", point ids
    (q,) int64 in order round it) for every opening on one side of the body's centre line that a limb fits
    through (``align.side_opening``): sleeve cuffs and armholes of the pieces over the
    shoulders, leg hems of the pieces hanging from the waist if there is one on each side (trousers, shorts;
    not a skirt's slit). A neck, waist or hem opening runs round the centre line and is none of them.
    ``loops``: the mesh's boundary loops if known (``GarmentModel.coarse_loops``); ``piece`` (k,) the points'
    ``pieces.piece_labels`` if known."""
    if "torso" not in body.parts or not any(f"{p}_{c}" in body.parts for ps in LIMB_PARTS.values() for p in ps
                                            for _, c, _ in SIDES):
        return []  # a scene's ball or table: no limbs
    lm = body_landmarks(body)
    bottom = bottom_mask(x, faces, category, piece)
    out = []
    for loop in boundary_loops(faces, len(x)) if loops is None else loops:
        loop = loop[ring_order(x[loop])]
        # a sleeve may be made at any angle to this body's arm (the DiffCloth dress's hang down to its
        # hips, nearer the thighs than the arms): which piece an opening is on says which limb it is for
        limb = "leg" if bottom[loop].all() else "arm"
        for side, _, sign in SIDES:
            if side_opening(x[loop], lm, sign):  # not a hole in the mesh, nor a neck, waist or hem
                out.append((side, limb, loop))
    # trousers have a leg opening on each side; a single one is a skirt's slit or a hole in the mesh
    leg_sides = {side for side, limb, _ in out if limb == "leg"}
    return [o for o in out if o[1] == "arm" or len(leg_sides) == 2]


def ring_order(points: np.ndarray) -> np.ndarray:
    """(q,) int64: the points (q, 3) of an opening in order round it, by angle about their centre in their
    best-fitting plane (an opening of the aligned garment, still the ring it was made as)."""
    rel = points - points.mean(axis=0)
    _, _, vt = np.linalg.svd(rel, full_matrices=False)
    return np.argsort(np.arctan2(rel @ vt[1], rel @ vt[0]))


def around_part(ring: np.ndarray, a: np.ndarray, b: np.ndarray, surface: np.ndarray) -> bool:
    """Whether the opening ``ring`` (q, 3) m, its points in order round it (``ring_order``), goes round the
    limb part whose axis runs from a to b (3,) m and whose surface vertices are ``surface`` (p, 3) m: seen
    along the axis it winds once round the centre of the part's cross-section there (a winding number,
    so a wide armhole that the arm passes through near its edge counts, and a cuff beside the limb does
    not), its middle lies along the part and within ``MAX_RADIUS`` of it."""
    axis = b - a
    length = float(np.linalg.norm(axis))
    if len(ring) < 3 or length == 0.0:
        return False
    axis = axis / length
    t = float(np.median((ring - a) @ axis))
    # the slice of the part nearest the opening (an armhole lies round the shoulder joint, where the
    # upper arm begins)
    t_slice = min(max(t, SECTION_HALF), length - SECTION_HALF)
    section = np.abs((surface - a) @ axis - t_slice) < SECTION_HALF
    if not ALONG[0] <= t / length <= ALONG[1] or section.sum() < 3:
        return False
    rel = ring - surface[section].mean(axis=0)
    radial = rel - (rel @ axis)[:, None] * axis
    if float(np.linalg.norm(radial, axis=1).mean()) > MAX_RADIUS:
        return False
    u = np.cross(axis, [0.0, 0.0, 1.0])
    if np.linalg.norm(u) < 1e-6:  # an axis along z
        u = np.cross(axis, [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    angles = np.arctan2(radial @ np.cross(axis, u), radial @ u)
    turn = np.diff(np.append(angles, angles[0]))
    turn = (turn + np.pi) % (2 * np.pi) - np.pi  # each step's angle, in [-pi, pi)
    return abs(float(turn.sum())) > np.pi  # the winding number rounds to +-1


def through_root(ring: np.ndarray, body: Body, k: int) -> bool:
    """Whether the limb whose first part is k (an upper arm or a thigh) passes through the opening ``ring`` (q,
    3) m round its root (its middle within ``ROOT_REACH`` of the part's length from the joint): the path from the
    torso's axis, level with the limb's joint, out to the joint and along the part's axis to its end crosses a
    fan of triangles spanning the ring an odd number of times (the limb links the ring; a ring hanging beside
    the limb, or slid off the shoulder, is crossed by neither segment). For an armhole seen along an arm raised
    forwards: the sleeveless dresses' armholes lay along the arm, a sliver beside its axis in that view."""
    a, b = body.part_axes[k]
    length = float(np.linalg.norm(b - a))
    if "torso" not in body.parts or length == 0.0 or len(ring) < 3:
        return False
    if float(np.median((ring - a) @ (b - a))) > ROOT_REACH * length * length:
        return False
    t0, t1 = body.part_axes[body.parts.index("torso")]
    trunk = t0 + np.clip((a - t0) @ (t1 - t0) / ((t1 - t0) @ (t1 - t0)), 0.0, 1.0) * (t1 - t0)
    centre = ring.mean(axis=0)
    v1, v2 = ring - centre, np.roll(ring, -1, axis=0) - centre  # the fan's triangles (centre, r_i, r_i+1)
    crossings = 0
    for start, end in ((trunk, a), (a, b)):
        d = end - start
        h = np.cross(d, v2)
        det = np.einsum("ij,ij->i", v1, h)
        ok = np.abs(det) > 1e-15
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = start - centre
        u = inv * (h @ s)
        q = np.cross(s, v1)
        v = inv * (q @ d)
        t = inv * np.einsum("ij,ij->i", v2, q)
        crossings += int((ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t < 1)).sum())
    return crossings % 2 == 1


def openings_on_limbs(x: np.ndarray, body: Body, openings: list[tuple[str, str, np.ndarray]]) -> list[dict]:
    """Where each opening (``limb_openings``) ended, for the draped coarse points x (k, 3) m:
    {"opening": "left arm" ..., "around": the part of that limb it winds round (``around_part``:
    "upper_arm_l" ...; the one nearer the trunk if both) or None, "past_end": whether it hangs past the limb's end (a sleeve
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
            if around_part(x[loop], a, b, part_points(body, k)) or (
                    part == LIMB_PARTS[limb][0] and through_root(x[loop], body, k)):
                around = name
                break
            # measured on the last part (forearm with hand, shin with foot): its axis ends at the limb's end,
            # and the opening must hang there, not lie anywhere beyond (a shirt slid off onto the floor)
            past_end = bool(np.median((x[loop] - a) @ (b - a)) > END_FRACTION * ((b - a) @ (b - a))
                            and np.linalg.norm(x[loop].mean(axis=0) - b) < MAX_RADIUS)
        out.append({"opening": f"{side} {limb}", "around": around, "past_end": past_end and around is None,
                    "ok": around is not None or past_end})
    return out


def shown_openings(model, openings: list[tuple[str, str, np.ndarray]]) -> list[tuple[str, str, np.ndarray]]:
    """The openings ``openings`` (``limb_openings``, on the coarse mesh of ``model``, a ``GarmentModel``) as
    loops of the shown (full) mesh: for each, the full boundary loop holding most of its coarse points, in
    order round it on the garment's own shape (``ring_order``); none for an opening no full loop holds."""
    full_loops = model.loops
    owner = np.full(len(model.vertices), -1, dtype=np.int64)
    for k, loop in enumerate(full_loops):
        owner[loop] = k
    out = []
    for side, limb, loop in openings:
        held = owner[model.coarse_index[loop]]
        held = held[held >= 0]
        if not len(held):
            continue
        full = full_loops[int(np.bincount(held).argmax())]
        out.append((side, limb, full[ring_order(model.vertices[full])]))
    return out


def openings_on_shown_limbs(x: np.ndarray, full: np.ndarray, model, body: Body,
                            openings: list[tuple[str, str, np.ndarray]]) -> list[dict]:
    """``openings_on_limbs`` judged on the simulated points x (k, 3) m and, for an opening not around its limb
    there, on the shown mesh ``full`` (n, 3) m: the cloth a person sees. A tight hem of few coarse points can
    miss its limb's centre while the cloth round it does not (the MakeHuman trousers on a 163 cm ANSUR body: a
    ten-point coarse hem chorded across the ankle, the shown hem's eighteen round it)."""
    coarse = openings_on_limbs(x, body, openings)
    if all(o["ok"] for o in coarse):
        return coarse
    rings = shown_openings(model, [o for o, c in zip(openings, coarse) if not c["ok"]])
    seen = {o["opening"]: o for o in openings_on_limbs(full, body, rings) if o["ok"]}
    return [seen.get(o["opening"], o) for o in coarse]
