"""Fit metrics of a drape: penetration and strain (SPEC section 7)."""

from __future__ import annotations

import numpy as np
from numba import njit

from scipy.spatial import cKDTree

from tryon.garment.springs import SPRING_KINDS
from tryon.sim.constraints import spring_strain
from tryon.sim.length import ankle_y, forearm
from tryon.sim.pieces import piece_tops

# m: a garment vertex deeper than this inside the un-offset body counts as penetrating (SPEC 7).
PENETRATION_TOLERANCE = 0.002


# Relative and absolute tolerance of the strain target (see ``strain_metrics``).
STRAIN_TOLERANCE = 0.01
LENGTH_TOLERANCE = 0.0002  # m


def allowed_length(rest: np.ndarray, limit) -> np.ndarray:
    """Longest length (m) a spring of natural length ``rest`` may have and still meet the strain target."""
    lmax = rest * (1.0 + limit)
    return np.maximum(lmax * (1.0 + STRAIN_TOLERANCE), lmax + LENGTH_TOLERANCE)


def springs_over(strain: np.ndarray, model, limits: np.ndarray,
                 on_body: np.ndarray | None = None) -> np.ndarray:
    """(s,) bool: the springs whose strain (s,) misses the target (longer than ``allowed_length`` for
    their kind's limit in ``limits`` (3,)); with ``on_body`` (k,) bool, only those with both ends on the
    body."""
    over = (1.0 + strain) * model.rest > allowed_length(model.rest, limits[model.kind])
    if on_body is not None:
        over &= on_body[model.springs[:, 0]] & on_body[model.springs[:, 1]]
    return over


@njit(cache=True, nogil=True)
def vertex_max_strain(n_vertices, springs, strain):
    """Largest strain of each coarse vertex's springs, (k,) float64 (0 for a vertex without springs)."""
    out = np.zeros(n_vertices)
    for s in range(springs.shape[0]):
        for c in range(2):
            v = springs[s, c]
            if strain[s] > out[v]:
                out[v] = strain[s]
    return out


def strain_metrics(coarse: np.ndarray, model, limits: np.ndarray,
                   on_body: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """Per-spring strain (s,), per full-mesh vertex strain (n,), and per-kind {max, limit, over} (plus
    ``over_on_body`` when ``on_body`` (k,) bool, coarse points touching the body, is given).

    The full-mesh strain interpolates the coarse vertices' strains with the re-attachment barycentrics
    (within the range of its triangle's corners).
    ``over``: how many springs exceed their kind's limit by more than 1 % (l > 1.01 l_max), or by 0.2 mm
    for springs shorter than 2 cm (triangle collapse leaves springs down to 1 mm, whose strain is noise:
    a 0.1 mm nudge by the collision is 10 %).
    ``over_on_body``: how many of those have both ends on the body: stretched around it (a garment too
    small for the body there, a band on the hips), where the cloth cannot shorten them without entering
    the body; the others are stretched in free cloth (the solver's residual, or a fold caught between
    two parts).
    """
    strain = spring_strain(coarse, model.springs, model.rest)
    per_coarse = vertex_max_strain(len(coarse), model.springs, strain)
    corners = model.coarse_faces[model.attach_face]  # (n, 3)
    # re-attachment barycentrics may lie a little outside [0, 1] (a full vertex just off its coarse
    # triangle): keep the interpolation within its corners' strains
    corner_strain = per_coarse[corners]
    per_full = np.clip(np.einsum("nj,nj->n", model.attach_bary, corner_strain), corner_strain.min(axis=1),
                       corner_strain.max(axis=1))
    over = springs_over(strain, model, limits)
    over_on_body = springs_over(strain, model, limits, on_body) if on_body is not None else None
    by_kind = {}
    for k, name in enumerate(SPRING_KINDS):
        sel = model.kind == k
        if not sel.any():
            continue
        by_kind[name] = {
            "max": float(strain[sel].max()),
            "limit": float(limits[k]),
            "over": int(over[sel].sum()),
        }
        if over_on_body is not None:
            by_kind[name]["over_on_body"] = int(over_on_body[sel].sum())
    return strain, per_full, by_kind


def penetration_metrics(depth: np.ndarray) -> dict:
    """Count of vertices deeper than 2 mm and the deepest (mm), from per-vertex depths (n,) in metres."""
    return {
        "penetrating_vertices": int((depth > PENETRATION_TOLERANCE).sum()),
        "max_penetration_mm": float(depth.max() * 1000.0) if len(depth) else 0.0,
    }


def deepest_inside(collider, x: np.ndarray) -> float:
    """Depth (m) of the deepest of the points ``x`` (k, 3) m inside the real (un-offset) body as ``collider`` (a
    ``collision.collider.BodyCollider``) has it now, its limbs where a re-pose has turned them this step; 0 when
    none is inside. Every part is tested, not only those the drape collides with: a point inside a part the
    garment was not expected to reach counts too. The collision's own inside test and nearest-surface depth
    (``collision.kernels.penetration_depth``); the surface is recomputed only when the body moved since the
    last call (the T-shirt M's 874 points: ~0.4 ms a call on a resting body, ~1.2 ms while it moves)."""
    parts = np.arange(len(collider.body.parts), dtype=np.int64)
    depth = collider.depth(x, parts, offset=False)
    return float(depth.max()) if len(depth) else 0.0


# cm: a garment whose top ended lower than this under where it was put on does not stay up on the body (a
# waistband wider than the hips, straps wider than the shoulders). In the default pose the catalogue's and
# the real garments that stay up slid at most 8 cm (the small body's skirt M, its band on the hips); the
# others 12 cm (the medium body's shorts L, resting lower on its hips) to 135 cm (a strap dress on the floor).
SLID_LIMIT_CM = 10.0


def slid_metrics(placed_tops: np.ndarray, x: np.ndarray, piece: np.ndarray) -> dict:
    """How far the garment slid down on the body: ``slid_cm``, the largest drop of a piece's highest point
    from where it was put on (``placed_tops`` (p,) m, ``piece_tops`` of the start) to where it ended (x
    (k, 3) m), in cm; ``stays_up``: whether that is within SLID_LIMIT_CM (a garment that slid off its
    shoulders or hips meets every strain and penetration target lying on the floor)."""
    slid = 100.0 * float(np.max(placed_tops - piece_tops(x, piece))) if len(piece) else 0.0
    return {"slid_cm": slid, "stays_up": bool(slid <= SLID_LIMIT_CM)}


def too_tight_places(coarse: np.ndarray, model, strain: np.ndarray, limits: np.ndarray, on_body: np.ndarray,
                     body, full: np.ndarray | None = None) -> dict[str, int]:
    """Where the garment is too small for the body, each place with how many springs say so, largest count first;
    empty when it is nowhere. Two kinds of spring say so, both with both ends on the body (``on_body`` (k,) bool,
    the coarse points touching it; a shown vertex is on it when its coarse triangle's three corners are):

    - a simulated spring held over its limit (``springs_over`` of its strain (s,), as ``strain_metrics`` counts);
    - an edge or quad diagonal of the shown mesh ``full`` (n, 3) m longer than at rest by more than the cloth's
      loosest in-plane limit (the shear limit, ``limits`` (3,) by kind) and ``SHOWN_TOLERANCE``: the cloth a
      shopper sees stretched past what it can stretch, where the coarse springs, meeting their limits, let their
      triangles shear across a body larger than the garment (a jersey dress M on a size XL body: its waist's
      shown edges at 22 %, no simulated spring over); at least ``SHOWN_MIN_EDGES`` of them at a place.

    Springs of either kind past a wrist or below an ankle bone do not count: a garment is not sized round a hand
    or a foot, and a cuff or hem caught there is its length (``length.garment_ends``), not a girth. Nor do those
    pinched between the body's left and right sides (``between_sides``: a crotch seam caught between the thighs,
    where a rise longer than the body's hangs): that is not a girth of either leg.

    A place is a limb part's name (``upper_arm_l``, ``thigh_r``...), or for the torso its band (``torso chest``,
    ``torso waist``, ``torso hips``: the nearest of the body's girth levels), of the body point nearest the
    spring's middle; its count the larger of the two kinds'."""
    over = springs_over(strain, model, limits, on_body)
    middle = 0.5 * (coarse[model.springs[over, 0]] + coarse[model.springs[over, 1]])
    middle = middle[~beyond_limb_ends(middle, body)]
    shown = shown_over_on_body(full, model, limits, on_body, body) if full is not None else np.zeros((0, 3))
    # one search of the body for both kinds: their places, and which are pinched between its sides
    points = np.concatenate([middle, shown])
    names = _place_names(points, body)
    counted = ~between_sides(points, body)
    k = len(middle)
    places = _counts(names[:k][counted[:k]])
    for place, n in _counts(names[k:][counted[k:]]).items():
        if n >= SHOWN_MIN_EDGES:
            places[place] = max(n, places.get(place, 0))
    return dict(sorted(places.items(), key=lambda item: -item[1]))


# Of length: the shown mesh's edges follow the coarse mesh in 3 rounds of stretch passes that end on the
# collision, which leaves a few edges up to a per cent over the limit they were held to (the 60 fitting drapes
# of the fit bench: shown edges at most 0.159 with a 0.15 shear limit).
SHOWN_TOLERANCE = 0.01
# Shown edges over that at a place before it is too tight: fewer is an edge or two the stretch passes left, not a
# patch of cloth (the real DiffAvatar long-sleeve shirt and polo on fitting bodies: one edge each at 0.17-0.19 of
# their ~20,000; a size too small: tens to thousands at each place).
SHOWN_MIN_EDGES = 3


def shown_over_on_body(full: np.ndarray, model, limits: np.ndarray, on_body: np.ndarray, body) -> np.ndarray:
    """Middles (m, 3) m of the shown mesh's springs (``model.display_springs`` at ``full`` (n, 3) m) stretched past
    the loosest in-plane limit of ``limits`` (3,) by ``SHOWN_TOLERANCE``, both ends on the body (their coarse
    triangles' corners in ``on_body`` (k,) bool), neither past a wrist nor below an ankle bone (see
    ``too_tight_places``)."""
    pairs, rest, _ = model.display_springs
    if not len(rest):
        return np.zeros((0, 3))
    length = np.linalg.norm(full[pairs[:, 0]] - full[pairs[:, 1]], axis=1)
    limit = float(np.max(limits[:2])) + SHOWN_TOLERANCE
    touching = on_body[model.coarse_faces[model.attach_face]].all(axis=1)
    over = (length > np.maximum(rest * (1.0 + limit), rest + LENGTH_TOLERANCE)) & touching[pairs].all(axis=1)
    middle = 0.5 * (full[pairs[over, 0]] + full[pairs[over, 1]])
    return middle[~beyond_limb_ends(middle, body)]


def beyond_limb_ends(points: np.ndarray, body) -> np.ndarray:
    """(m,) bool: the points (m, 3) m below the body's ankle bones (``length.ankle_y``) or
    past a wrist joint along its forearm (elbow to wrist); none for a body without joints."""
    out = np.zeros(len(points), dtype=np.bool_)
    if not body.joints or "height" not in body.achieved or not len(points):
        return out
    out |= points[:, 1] < ankle_y(body)
    for s in ("l", "r"):
        wrist, axis = forearm(body, s)
        along = (points - wrist) @ axis
        across = np.linalg.norm(points - wrist - along[:, None] * axis, axis=1)
        out |= (along > 0.0) & (along < HAND_LENGTH) & (across < HAND_REACH)
    return out


def between_sides(points: np.ndarray, body) -> np.ndarray:
    """(m,) bool: the points (m, 3) m within ``PINCH_REACH`` of both a left part of the body and a right one
    (``body.parts`` ending in ``_l`` / ``_r``): cloth pinched between the thighs, the shins, two crossed
    forearms."""
    out = np.zeros(len(points), dtype=np.bool_)
    if not len(points):
        return out
    side = np.array([p[-2:] for p in body.parts])[body.vertex_part]
    near = [cKDTree(body.vertices[side == s]).query(points, distance_upper_bound=PINCH_REACH)[0] < PINCH_REACH
            for s in ("_l", "_r") if (side == s).any()]
    return near[0] & near[1] if len(near) == 2 else out


# m: how close to both a left and a right part of the body a spring's middle is when pinched between them. The
# crotch seams of trousers whose rise hangs between the thighs (ANSUR II people in the chart's size, and
# larger) lie 2-15 mm from each thigh; a thigh's own girth springs are a thigh's width from the other.
PINCH_REACH = 0.015


# m: a point past a wrist joint along the forearm, by at most HAND_LENGTH and within HAND_REACH of the forearm's
# line, is on the hand (a hand is about 19 cm long and 8-9 cm wide, its fingers spread a little more).
HAND_LENGTH = 0.20
HAND_REACH = 0.12


def _counts(names: np.ndarray) -> dict[str, int]:
    """How many times each place name occurs in ``names``."""
    places, counts = np.unique(names.astype(str), return_counts=True)
    return {str(p): int(c) for p, c in zip(places, counts)}


def _place_names(middle: np.ndarray, body) -> np.ndarray:
    """(m,) object: the body place of each of the points ``middle`` (m, 3) m (see ``too_tight_places``)."""
    if not len(middle):
        return np.zeros(0, dtype=object)
    part = body.vertex_part[cKDTree(body.vertices).query(middle)[1]]
    names = np.array(body.parts, dtype=object)[part]
    levels = {k: v for k, v in (body.levels or {}).items() if k in ("chest", "waist", "hips")}
    if levels:
        level_names = list(levels)
        band = np.argmin(np.abs(middle[:, 1, None] - np.array([levels[k] for k in level_names])[None]), axis=1)
        torso = names == "torso"
        names[torso] = [f"torso {level_names[b]}" for b in band[torso]]
    return names
