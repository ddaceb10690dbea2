"""Sleeves (alignment): which openings of a top are its cuffs (``sleeve_openings``, ``side_opening``), the cloth
from cuff to armpit (``find_sleeves``: cloth distance along the mesh), its rings along the arm
(``sleeve_rings``), each sleeve widened round its arm to at least ``LEG_EASE`` x the arm's girth
(``fit_sleeve``). From the aligned garment points (k, 3) m, its faces and openings, and the body."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from tryon.body.types import Body
from tryon.garment.topology import cloth_distance
from tryon.sim.landmarks import BodyLandmarks, arm_joints, part_index, part_points
from tryon.sim.legs import LEG_BIN, LEG_EASE
from tryon.sim.pieces import union_root

# m: beyond a guessed-units top's bodice its depth scale fades to none over this distance (the armhole;
# see ``scale_girth_keep_sleeves``): over 5 cm an edge across it was stretched up to 1.7 x the scale
# (3.1 x on the MakeHuman blouse at scale 1.8), over 15 cm 1.0-1.05 x.
SLEEVE_BLEND = 0.15
# m: a guessed-units top's sleeve is measured in rings about this far apart over the cloth from its cuff
# (``sleeve_rings``), each of MIN_RING_POINTS points or more (the coarse MakeHuman blouse's sleeves have
# rings of one point: no girth to speak of). A sleeve is widened to at most MAX_SLEEVE_EASE x its girth (the
# MakeHuman blouse on the large body: 1.9 x at the cuff, made for a slimmer arm).
SLEEVE_RING = 0.04
MIN_RING_POINTS = 4
MAX_SLEEVE_EASE = 2.0
# A sleeve's points lie beyond this many torso half-widths from the centre (past the bodice of a fitted top
# or dress), above the chest-to-waist mid level; a side with fewer than MIN_SLEEVE_POINTS such points has
# no sleeve. The torso's width, not the shoulder joints': the upper arm's axis starts in its rounded cap,
# which moves out by 2 cm as the arm comes down from 30 degrees to hanging, and 1.4 of the joints'
# half-width at arm angle 0 lay beyond the catalogue T-shirt M's cuffs (no sleeve found, no arm turned,
# the arms inside the bodice). 1.07 is 1.4 joint half-widths at the default 30 degrees on the small,
# medium and large bodies (within 1 mm).
SLEEVE_REACH = 1.07
MIN_SLEEVE_POINTS = 8
# An opening on one side of the body (a sleeve's cuff, an armhole, a trouser hem) has at least this fraction
# of its points on that side of the centre line (a neck, waist or hem opening runs round it).
OPENING_SHARE = 0.8
# m: an opening shorter round than this is a hole in the mesh: no wrist or ankle fits through it.
MIN_PERIMETER = 0.12


class Sleeve(NamedTuple):
    """A top's sleeve found over the cloth (``find_sleeves``): every point's cloth distance (k,) m from its
    cuff, and the armpit's (m); the sleeve is the points nearer the cuff than the armpit."""

    distance: np.ndarray
    armpit: float


def find_sleeves(x: np.ndarray, faces: np.ndarray, openings: list[np.ndarray], lm: BodyLandmarks
                 ) -> dict[float, Sleeve]:
    """Each side's sleeve of a top (points x (k, 3), faces (f, 3), boundary loops ``openings``), keyed by
    side (+1.0: the body's left): the opening on that side (``side_opening``) farthest from the shoulder
    joint is its cuff if it hangs from an armpit (``armpit_distance``). By the cloth, not by reach: a
    T-shirt at 0.7 of its girth has its sleeves within ``SLEEVE_REACH`` (it was scaled as if it had none,
    its girth measured round its sleeves), a sleeveless armhole or a cape's hem has no armpit."""
    out = {}
    for sign, joint in ((1.0, lm.shoulder_l), (-1.0, lm.shoulder_r)):
        ends = [loop for loop in openings if side_opening(x[loop], lm, sign)]
        found = armpit_distance(x, faces, far_opening(x, ends, joint), lm) if ends else None
        if found is not None:
            out[sign] = found
    return out


def sleeve_points(n: int, sleeves: dict[float, Sleeve]) -> np.ndarray:
    """(n,) bool: the points of the ``sleeves`` (``find_sleeves``), from the armpit down."""
    out = np.zeros(n, dtype=np.bool_)
    for sleeve in sleeves.values():
        out |= sleeve.distance < sleeve.armpit
    return out


@njit(cache=True, nogil=True)
def _joining_face(faces, a, b, n):
    """Joining the corners of the triangles ``faces`` (f, 3) in their order: the index of the face that
    first joins the points a and b, and (n,) bool: the points joined to b before it; (-1, none, 0) if
    none does. Also how many points were joined to a before it."""
    parent = np.arange(n)
    size = np.ones(n, dtype=np.int64)
    for i in range(faces.shape[0]):
        ra, rb = union_root(parent, a), union_root(parent, b)
        r0, r1, r2 = (union_root(parent, faces[i, 0]), union_root(parent, faces[i, 1]),
                      union_root(parent, faces[i, 2]))
        if ra != rb and (ra == r0 or ra == r1 or ra == r2) and (rb == r0 or rb == r1 or rb == r2):
            joined = np.empty(n, dtype=np.bool_)
            for v in range(n):
                joined[v] = union_root(parent, v) == rb
            return i, joined, size[ra]
        for c in range(1, 3):
            r0, rc = union_root(parent, faces[i, 0]), union_root(parent, faces[i, c])
            if r0 != rc:
                parent[rc] = r0
                size[r0] += size[rc]
    return -1, np.zeros(n, dtype=np.bool_), 0


def armpit_distance(x: np.ndarray, faces: np.ndarray, cuff: np.ndarray, lm: BodyLandmarks) -> Sleeve | None:
    """The sleeve of a top (points x (k, 3), faces (f, 3)) whose cuff is the opening ``cuff`` (point ids),
    if it hangs from an armpit, else None. Faces added from the lowest up (by their highest corner), the
    armpit is where the part of the top below first joins the cuff's lowest point to the hem (the lowest
    point near the centre line): just before, the part joined to the hem is the bodice below the armpit,
    reached from the cuff over the cloth through the armpit, so the least cloth distance of its points is
    the armpit's. A sleeveless armhole's lowest point joins the bodice with its first face, a sleeve's cuff
    only after ``MIN_SLEEVE_POINTS`` of the sleeve have joined it; a sleeve held out level has none."""
    y = x[:, 1]
    near = np.abs(x[:, 0] - lm.center_x) < 0.5 * lm.shoulder_half
    if not near.any():
        return None
    hem = int(np.flatnonzero(near)[np.argmin(y[near])])
    low = int(cuff[np.argmin(y[cuff])])
    order = np.argsort(y[faces].max(axis=1), kind="stable")
    face, bodice, sleeve_size = _joining_face(np.ascontiguousarray(faces[order], dtype=np.int64), low, hem, len(x))
    if face < 0 or sleeve_size < MIN_SLEEVE_POINTS:
        return None
    d = cloth_distance(x, faces, cuff)
    return Sleeve(d, float(d[bodice].min()))


def ring_index(d: np.ndarray, armpit: float) -> tuple[np.ndarray, float]:
    """The ring round a sleeve each point lies in (k,) int (-1: beyond the armpit's ring), by its cloth
    distance ``d`` (k,) m from the cuff, the rings ``SLEEVE_RING`` or so apart from the cuff (ring 0) to
    the armpit (the last); and their spacing, m."""
    count = max(1, int(round(armpit / SLEEVE_RING)))
    spacing = armpit / count
    inside = d <= armpit + 0.5 * spacing
    return np.where(inside, np.rint(np.where(inside, d, 0.0) / spacing), -1).astype(np.int64), spacing


def sleeve_rings(x: np.ndarray, sleeve: Sleeve, joint: np.ndarray):
    """The rings round a sleeve (``ring_index``) of ``MIN_RING_POINTS`` points or more: (their ids (n,),
    centres (n, 3), unit tangents (n, 3) towards the armpit, radii (n,) m: the mean distance of a ring's
    points from its centre across the sleeve, and their places along the arm (n,) m from the shoulder
    ``joint`` (3,): the armpit ring centre's distance from it, then on down the ring centres). None with
    fewer than two rings."""
    ring, _ = ring_index(sleeve.distance, sleeve.armpit)
    inside = ring >= 0
    ring = ring[inside]
    counts = np.bincount(ring)
    ids = np.flatnonzero(counts >= MIN_RING_POINTS)
    if len(ids) < 2:
        return None
    sums = np.stack([np.bincount(ring, weights=x[inside, j]) for j in range(3)], axis=1)
    centres = sums[ids] / counts[ids, None]
    tangents = np.gradient(centres, ids, axis=0)
    tangents /= np.maximum(np.linalg.norm(tangents, axis=1, keepdims=True), 1e-12)
    kept = np.full(len(counts), -1)
    kept[ids] = np.arange(len(ids))
    k = kept[ring]
    mine = k >= 0
    rel = x[inside][mine] - centres[k[mine]]
    across = rel - np.einsum("ij,ij->i", rel, tangents[k[mine]])[:, None] * tangents[k[mine]]
    radii = np.bincount(k[mine], weights=np.linalg.norm(across, axis=1), minlength=len(ids)) / counts[ids]
    steps = np.linalg.norm(np.diff(centres, axis=0), axis=1)
    along = float(np.linalg.norm(centres[-1] - joint)) + np.concatenate([np.cumsum(steps[::-1])[::-1], [0.0]])
    return ids, centres, tangents, radii, along


def fit_sleeve(out: np.ndarray, x: np.ndarray, bodice: np.ndarray, sleeve: Sleeve, joint: np.ndarray,
               arm: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
    """``out`` (k, 3) with one sleeve of the top's points x (k, 3) moved with its armhole: by the move of
    its armpit ring's points from x to ``bodice`` (k, 3: the bodice's scale of every point), and widened
    about its rings' centres (``sleeve_rings``) to no less than ``LEG_EASE`` x the arm's girth along it
    (``arm``: the arm's joints and surface, ``arm_surfaces``; at most ``MAX_SLEEVE_EASE``), blending in
    from the bodice's scale at the armpit over ``SLEEVE_BLEND`` down the sleeve (or its whole length, if
    shorter). Unchanged if its rings are not found."""
    rings = sleeve_rings(x, sleeve, joint)
    if rings is None:
        return out
    ids, centres, tangents, radii, along = rings
    ring, spacing = ring_index(sleeve.distance, sleeve.armpit)
    armhole = ring == ids[-1]
    shift = (bodice[armhole] - x[armhole]).mean(axis=0)
    factor = np.ones(len(ids))
    if arm is not None:
        skin = arm_radii(arm[1], arm[0], along)
        factor = np.where(skin > 0, np.clip(LEG_EASE * skin / np.maximum(radii, 1e-9), 1.0, MAX_SLEEVE_EASE), 1.0)
    d = sleeve.distance
    weight = np.clip((sleeve.armpit - d) / min(SLEEVE_BLEND, sleeve.armpit), 0.0, 1.0)
    sel = weight > 0
    r = ids * spacing
    ds = d[sel]
    centre = np.stack([np.interp(ds, r, centres[:, j]) for j in range(3)], axis=1)
    tangent = np.stack([np.interp(ds, r, tangents[:, j]) for j in range(3)], axis=1)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    rel = x[sel] - centre
    across = rel - np.einsum("ij,ij->i", rel, tangent)[:, None] * tangent
    moved = x[sel] + shift + (np.interp(ds, r, factor) - 1.0)[:, None] * across
    out = out.copy()
    out[sel] = bodice[sel] + weight[sel, None] * (moved - bodice[sel])
    return out


def arm_surfaces(body: Body) -> dict[float, tuple[np.ndarray, np.ndarray]] | None:
    """Each arm's joints (3, 3) (shoulder, elbow, wrist end: ``arm_joints``) and its surface points (m, 3),
    upper arm and forearm, keyed by side (+1.0: the left arm, towards +x; -1.0: the right); None if the
    body has no forearms."""
    out = {}
    for sign, side in ((1.0, "l"), (-1.0, "r")):
        ku, kf = part_index(body, f"upper_arm_{side}"), part_index(body, f"forearm_{side}")
        if ku is None or kf is None:
            return None
        out[sign] = (np.array(arm_joints(body, side)), np.concatenate([part_points(body, ku), part_points(body, kf)]))
    return out


def arm_radii(points: np.ndarray, joints: np.ndarray, along: np.ndarray) -> np.ndarray:
    """Median distance (m) of an arm's surface points (m, 3) from its axis (the polyline ``joints`` (3, 3):
    shoulder, elbow, wrist end) in bands ``LEG_BIN`` long about the lengths ``along`` (h,) m down the axis
    from the shoulder joint; 0 where a band has none (past the wrist)."""
    place, dist, start = [], [], 0.0
    for a, b in zip(joints[:-1], joints[1:]):
        length = float(np.linalg.norm(b - a))
        u = np.clip((points - a) @ (b - a) / length ** 2, 0.0, 1.0)
        dist.append(np.linalg.norm(points - a - u[:, None] * (b - a), axis=1))
        place.append(start + u * length)
        start += length
    nearer = np.argmin(np.stack(dist), axis=0)  # a point belongs to the nearer of the two segments
    place, dist = np.choose(nearer, place), np.choose(nearer, dist)
    on_axis = (place > 0.0) & (place < start)
    out = np.zeros(len(along))
    for k, t in enumerate(along):
        near = on_axis & (np.abs(place - t) < 0.5 * LEG_BIN)
        if near.any():
            out[k] = float(np.median(dist[near]))
    return out


def sleeve_mask(x: np.ndarray, lm: BodyLandmarks, sign: float, reach: float = SLEEVE_REACH) -> np.ndarray:
    """(k,) bool: the points (k, 3) of the sleeve on one side (``sign`` +1: the body's left, towards +x):
    beyond ``SLEEVE_REACH`` x the torso's half-width from the centre (past the bodice of a fitted top or
    dress), above the chest-to-waist mid level."""
    beyond = (x[:, 0] - lm.center_x) * sign > reach * lm.torso_half
    return beyond & (x[:, 1] > 0.5 * (lm.chest_y + lm.waist_y))


def sleeve_openings(x: np.ndarray, lm: BodyLandmarks, sign: float, loops: list[np.ndarray],
                    upper: np.ndarray | None = None) -> list[np.ndarray]:
    """The openings (``loops``: boundary loops, index arrays into the points x (k, 3)) on one side (``sign``
    +1: the body's left) whose centre lies beyond ``SLEEVE_REACH`` x the torso's half-width, all of their
    points among ``upper`` (k,) bool if given: a sleeve's cuff. A cuff may hang below the level
    ``sleeve_mask`` takes sleeve points above, so only the reach counts here. The centre, not all the
    points: a short sleeve's cuff is a ring round the arm whose inner side may lie within the reach (the
    catalogue's T-shirts S-L on the large body: 57-71 % of their points beyond it), while a sleeveless
    bodice's armhole, however wide, is centred within it (at most 0.95 of the reach on the catalogue's
    three bodies; the cuffs at least 1.07)."""
    out = []
    for loop in loops:
        if upper is not None and not upper[loop].all():
            continue
        if (x[loop, 0].mean() - lm.center_x) * sign > SLEEVE_REACH * lm.torso_half:
            out.append(loop)
    return out


def side_opening(points: np.ndarray, lm: BodyLandmarks, sign: float) -> bool:
    """Whether an opening, its points (q, 3) in order round it, is one a limb fits through on one side of the
    body (``sign`` +1: the body's left): at least ``MIN_PERIMETER`` round, ``OPENING_SHARE`` of its points on
    that side of the centre line (a sleeve's cuff, an armhole, a trouser hem; not a neck, waist or hem)."""
    if len(points) < 3:
        return False
    if float(np.linalg.norm(points - np.roll(points, 1, axis=0), axis=1).sum()) < MIN_PERIMETER:
        return False
    return bool(((points[:, 0] - lm.center_x) * sign > 0).mean() >= OPENING_SHARE)


def has_sleeves(x: np.ndarray, lm: BodyLandmarks) -> bool:
    """Whether the top's points (k, 3) reach out like a sleeve (``MIN_SLEEVE_POINTS`` or more) on each
    side. Reach alone: the side of a bodice wider than the body's shoulders reaches as far, and only an
    opening out there (``sleeve_openings``) tells them apart."""
    return all(sleeve_mask(x, lm, sign).sum() >= MIN_SLEEVE_POINTS for sign in (1.0, -1.0))


def far_opening(x: np.ndarray, ends: list[np.ndarray], joint: np.ndarray) -> np.ndarray:
    """Of a sleeve's openings ``ends`` (index arrays into the points x (k, 3)), the one whose centre is
    farthest from the shoulder ``joint`` (3,): its cuff."""
    return max(ends, key=lambda loop: float(np.linalg.norm(x[loop].mean(axis=0) - joint)))
