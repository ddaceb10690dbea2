"""Trouser legs (alignment): where a bottom's crotch is (``garment_crotch``), the body's leg axes and radii, each
leg of the garment moved over its leg and widened to at least ``LEG_EASE`` x the leg's girth (``fit_legs``),
hems lifted clear of the feet (``clear_feet``). From the aligned garment points (k, 3) m and the body."""

from __future__ import annotations

import numpy as np

from tryon.body.types import Body
from tryon.garment.topology import face_edge_ids
from tryon.geometry import rotation
from tryon.sim.landmarks import BodyLandmarks, part_index, part_points
from tryon.sim.pieces import section_sides

# m: how far in front of the shin's axis the body's surface counts as the foot (the ankle's radius is
# 3-4 cm, the foot reaches 11-17 cm forward below ~5 cm), and how far above the feet a trouser hem is put
# (with 1 cm, once the legs were shortened from the real crotch, the small body's trousers S caught the
# front of a hem on the instep: 88 springs over down its shin; with 2 or 3 cm none are).
FOOT_REACH = 0.06
FOOT_CLEARANCE = 0.02
# A bottom has legs when its crotch is higher than this fraction of its height above its hem (shorts:
# ~0.3, trousers ~0.75; a skirt's section never parts).
MIN_LEG_FRACTION = 0.15
# m: the crotch is looked for in sections this far apart; a piece of a section counts with this many
# edges crossed or more (a leg of the coarse trousers crosses ~25).
CROTCH_STEP = 0.01
MIN_SECTION_EDGES = 3
# m: height of the bands in which a trouser leg's centre is measured, and the height below the crotch
# over which the leg's shift onto the body's leg blends in.
LEG_BIN = 0.08
LEG_BLEND = 0.10
# m: smallest offset between a trouser leg's centre and the body's leg axis worth moving the legs for:
# a leg within 5 cm still has the body's leg inside it (the catalogue's trousers, made for a reference
# body, are 0-4.3 cm off on the small, medium and large bodies, and moving them changed their drapes both
# ways; the MakeHuman outfits' trousers are 12-22 cm off).
MIN_LEG_SHIFT = 0.05
# A guessed-units bottom's legs keep their own girth, not the waistband's scale, but never less than this
# times the body's leg at each height (the MakeHuman T-shirt outfit's trousers end mid-calf, narrower than a
# large body's calf).
LEG_EASE = 1.1


def garment_crotch(x: np.ndarray, faces: np.ndarray, cx: float) -> float | None:
    """Height (m) of a bottom's crotch, to ``CROTCH_STEP``: the highest level, down from its top, whose
    section has a piece on each side of the centre line x = ``cx`` (``pieces.section_sides``); None for a
    skirt, whose section never parts. Its points (k, 3), its faces (f, 3). The lowest point near the
    centre line, used before, was the catalogue trousers' knees (their legs hang within 2 cm of each other
    down to there) and the shorts' hems (no crotch: shorts were taken for a skirt)."""
    y0, y1 = float(x[:, 1].min()), float(x[:, 1].max())
    edges, face_edges = face_edge_ids(faces)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    for y in np.arange(y1 - CROTCH_STEP, y0, -CROTCH_STEP):
        if all(section_sides(x, faces, face_edges, edges, float(y), cx, MIN_SECTION_EDGES)):
            return float(y) if y - y0 > MIN_LEG_FRACTION * (y1 - y0) else None
    return None


def leg_axes(body: Body) -> dict[float, np.ndarray] | None:
    """Each leg's axis as a polyline (3, 3) from the hip joint through the knee to the ankle, keyed by
    side (+1.0: the left leg, towards +x; -1.0: the right); None if the body has no legs."""
    out = {}
    for sign, side in ((1.0, "l"), (-1.0, "r")):
        kt, ks = part_index(body, f"thigh_{side}"), part_index(body, f"shin_{side}")
        if kt is None or ks is None:
            return None
        thigh, shin = body.part_axes[kt], body.part_axes[ks]
        out[sign] = np.array([thigh[0], 0.5 * (thigh[1] + shin[0]), shin[1]])
    return out


def leg_points(body: Body) -> dict[float, np.ndarray]:
    """Each leg's surface points (m, 3), thigh and shin, keyed by side as ``leg_axes``."""
    out = {}
    for sign, side in ((1.0, "l"), (-1.0, "r")):
        parts = [k for k in (part_index(body, f"thigh_{side}"), part_index(body, f"shin_{side}")) if k is not None]
        out[sign] = np.concatenate([part_points(body, k) for k in parts]) if parts else np.empty((0, 3))
    return out


def leg_radii(points: np.ndarray, axis: np.ndarray, heights: np.ndarray) -> np.ndarray:
    """Median horizontal distance (m) of a leg's surface points (m, 3) from its axis (``leg_axes``, a
    polyline running down) in bands ``LEG_BIN`` high about ``heights`` (h,); 0 where a band has none."""
    centres = axis_at(axis, heights)
    out = np.zeros(len(heights))
    for b, y in enumerate(heights):
        near = points[np.abs(points[:, 1] - y) < 0.5 * LEG_BIN]
        if len(near):
            out[b] = float(np.median(np.linalg.norm(near[:, [0, 2]] - centres[b], axis=1)))
    return out


def axis_at(axis: np.ndarray, heights: np.ndarray) -> np.ndarray:
    """(h, 2) x, z (m) of a leg's axis (``leg_axes``, a polyline running down) at ``heights`` (h,) m."""
    ay = axis[::-1, 1]  # the polyline runs downwards: reverse it for np.interp
    return np.stack([np.interp(heights, ay, axis[::-1, c]) for c in (0, 2)], axis=1)


def _leg_bands(x: np.ndarray, lm: BodyLandmarks, legs: dict[float, np.ndarray], crotch: float):
    """The height bands (``LEG_BIN``) of a bottom's points (k, 3) below ``crotch`` and each trouser leg in
    them: (edges (n_bins + 1,), centres (n_bins,), {side sign: (leg mask (k,), its centre in each band
    (n_bins, 2) x, z, the body leg's axis there (n_bins, 2))}), or None when a leg has a band without
    points (shorts too short for the bands, a skirt)."""
    y = x[:, 1]
    low = float(y.min())
    n_bins = max(2, int(np.ceil((crotch - low) / LEG_BIN)))
    edges = np.linspace(low, crotch, n_bins + 1)
    centres = 0.5 * (edges[:-1] + edges[1:])
    found = {}
    for sign, axis in legs.items():
        leg = (sign * (x[:, 0] - lm.center_x) > 0) & (y < crotch)
        if leg.sum() < 3 * n_bins:
            return None
        centre = _leg_centres(x, leg, edges)
        if centre is None:
            return None
        found[sign] = (leg, centre, axis_at(axis, centres))
    return edges, centres, found


def _band_of(heights: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """The band (index) each height (m) falls in, bands bounded by ``edges`` (n_bins + 1,)."""
    return np.clip(np.searchsorted(edges, heights) - 1, 0, len(edges) - 2)


def _band_mean(band: np.ndarray, values: np.ndarray, n_bins: int) -> np.ndarray:
    """(n_bins,) mean of the values in each band (every band must hold one)."""
    return np.bincount(band, weights=values, minlength=n_bins) / np.bincount(band, minlength=n_bins)


def _leg_centres(x: np.ndarray, leg: np.ndarray, edges: np.ndarray) -> np.ndarray | None:
    """(n_bins, 2) x, z of the leg's (mask ``leg``) centre in each band, or None if a band is empty."""
    n_bins = len(edges) - 1
    b = _band_of(x[leg, 1], edges)
    if (np.bincount(b, minlength=n_bins) == 0).any():
        return None
    return np.stack([_band_mean(b, x[leg, c], n_bins) for c in (0, 2)], axis=1)


def leg_girth(x: np.ndarray, lm: BodyLandmarks, legs: dict[float, np.ndarray], crotch: float, girth: float,
              leg_surface: dict[float, np.ndarray] | None = None) -> np.ndarray:
    """A bottom's points (k, 3) with each trouser leg scaled by ``girth`` about its centres, around the leg
    (x, z), blending in over ``LEG_BLEND`` below the crotch (undoing a guessed-units girth scale,
    ``_align_piece``), but not to less than ``LEG_EASE`` x the body's leg (``leg_surface``: its points by
    side, ``leg_points``), widened past the scaled girth where even that is narrower: a hem too narrow for the
    calf would start inside it (the MakeHuman T-shirt outfit's trousers, ending mid-calf on a 178 cm ANSUR
    body: a ten-point coarse hem 42 mm round a 49 mm calf, off the shin within the body's growth).
    ``crotch``: the garment's (``garment_crotch``); ``legs``: the body's leg axes (``leg_axes``). Unchanged
    without two legs."""
    bands = _leg_bands(x, lm, legs, crotch)
    if bands is None or girth == 1.0:
        return x
    edges, centres, found = bands
    x = x.copy()
    for sign, (leg, centre, _) in found.items():
        blend = np.clip((crotch - x[leg, 1]) / LEG_BLEND, 0.0, 1.0)[:, None]
        mids = np.stack([np.interp(x[leg, 1], centres, centre[:, j]) for j in range(2)], axis=1)
        rel = x[leg][:, [0, 2]] - mids
        radius = _band_mean(_band_of(x[leg, 1], edges), np.linalg.norm(rel, axis=1), len(centres))
        skin = leg_radii(leg_surface[sign], legs[sign], centres) if leg_surface is not None else 0.0
        factor = np.interp(x[leg, 1], centres, np.maximum(LEG_EASE * skin / radius, girth))
        x[np.flatnonzero(leg)[:, None], [0, 2]] = mids + rel * (1.0 + blend * (factor[:, None] - 1.0))
    return x


def fit_legs(x: np.ndarray, lm: BodyLandmarks, legs: dict[float, np.ndarray], crotch: float) -> np.ndarray:
    """Move each trouser leg of the bottom points (k, 3) over the body's leg. First the leg is turned,
    rigidly, from its own direction (a line through its centres, the mean of its points in bands) onto the
    body leg's, about its centre at the crotch; then its centre at each height is moved onto the body's leg
    axis. Both blend in over ``LEG_BLEND`` below the crotch so the seat does not move. A garment modelled on
    a body standing with its feet further apart (MakeHuman) or closer together (the catalogue's trousers on
    legs spread 20 degrees) otherwise starts with the body's shins outside its legs, and the collision pulls
    the legs across (twisted or splayed legs). Moving the centres alone shears a leg: on legs spread 20
    degrees the trousers M started with 816 springs over their limits, strained up to 69 %. ``crotch``: its
    height (``garment_crotch``). Nothing moves when no leg is off by ``MIN_LEG_SHIFT``."""
    bands = _leg_bands(x, lm, legs, crotch)
    if bands is None:
        return x
    edges, centres, found = bands
    if max(np.abs(target - centre).max() for _, centre, target in found.values()) < MIN_LEG_SHIFT:
        return x
    x = x.copy()
    for sign, (leg, centre, target) in found.items():
        blend = np.clip((crotch - x[leg, 1]) / LEG_BLEND, 0.0, 1.0)[:, None]
        # the leg's direction: a line x, z = a + b y through the centres of the bands below the blend
        below = centres < crotch - LEG_BLEND
        if below.sum() >= 2:
            slope = np.polyfit(centres[below], centre[below], 1)[0]  # (2,) dx/dy, dz/dy
            own = -np.array([slope[0], 1.0, slope[1]])
            own /= np.linalg.norm(own)
            body_dir = legs[sign][-1] - legs[sign][0]
            body_dir /= np.linalg.norm(body_dir)
            turn_axis = np.cross(own, body_dir)
            sin_a = float(np.linalg.norm(turn_axis))
            if sin_a > 1e-6:
                turn = rotation(turn_axis / sin_a, float(np.arctan2(sin_a, own @ body_dir)))
                top = np.array([np.interp(crotch, centres, centre[:, 0]), crotch,
                                np.interp(crotch, centres, centre[:, 1])])
                x[leg] += blend * ((x[leg] - top) @ turn.T + top - x[leg])
                centre = _leg_centres(x, leg, edges)
        d = target - centre
        for j, c in enumerate((0, 2)):
            x[leg, c] += blend[:, 0] * np.interp(x[leg, 1], centres, d[:, j])
    return x


def foot_top(body: Body) -> float | None:
    """Height (m) of the top of the feet: the highest point of the shins' surface more than ``FOOT_REACH``
    in front of their axis at its height, in their lower half (the instep); None if the body has no
    shins."""
    tops = []
    for side in ("l", "r"):
        k = part_index(body, f"shin_{side}")
        if k is None:
            return None
        v = part_points(body, k)
        (_, y0, z0), (_, y1, z1) = body.part_axes[k]  # knee to ankle
        axis_z = z0 + (z1 - z0) * np.clip((v[:, 1] - y0) / (y1 - y0), 0.0, 1.0)
        ahead = (v[:, 2] - axis_z > FOOT_REACH) & (v[:, 1] < 0.5 * (y0 + y1))  # not the knee cap
        if ahead.any():
            tops.append(float(v[ahead, 1].max()))
    return max(tops) if tops else None


def clear_feet(x: np.ndarray, crotch: float, foot_y: float) -> np.ndarray:
    """A bottom's points (k, 3) whose legs reach below ``foot_y`` + ``FOOT_CLEARANCE`` (trousers made for a
    taller body, or whose hem lies on the floor) with the legs shortened from the crotch down, uniformly,
    so that the hem starts just above the feet: a hem placed through the feet starts with each foot
    through the leg's front (the springs across the instep, which growth cannot undo: no point is inside),
    and the foot keeps the leg caught. The legs' springs start folded (``start``: no compression correction)
    and lengthen again as gravity draws the hem down around the foot. ``crotch``: its height
    (``garment_crotch``). Nothing changes for shorts."""
    target = foot_y + FOOT_CLEARANCE
    hem = float(x[:, 1].min())
    if hem >= target or crotch <= target:
        return x
    x = x.copy()
    legs = x[:, 1] < crotch
    x[legs, 1] = crotch - (crotch - x[legs, 1]) * (crotch - target) / (crotch - hem)
    return x
