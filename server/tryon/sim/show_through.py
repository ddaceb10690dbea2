"""Body through cloth: body points that poke out through the shown garment where it covers them.

The penetration metric (SPEC 7) counts garment vertices inside the body. It cannot see the opposite
fault: every vertex of a garment outside the body while a triangle between them cuts under the skin (a
coarse triangle across a shoulder, a sleeve pulled tight over an elbow), so that skin shows through the
cloth on the page. This module measures that on the mesh the shopper sees.

For each body vertex p with outward normal n (of the body's current shape) near the garment, the line
p + t n, t in [-PROBE_IN, +PROBE_OUT], is cut with the shown garment's triangles. The cloth covers p when
the line meets it; the outermost crossing t_max is the cloth layer the eye sees there. When t_max <
-tolerance, that outermost layer lies under the skin: the body shows through by -t_max. Body vertices
inside another body part (an arm's root inside the torso) are hidden skin and not counted.

``lift_over_skin`` mends it where the shown mesh is built (``full_mesh.follow_coarse``): each body vertex whose
outermost layer lies under the skin, by at most ``full_mesh.SKIN_DEEPEST``, lifts that triangle along the
vertex's normal out to the offset surface; the stretch passes that follow spread the lift.

The crossings come from a uniform grid over the garment's triangles (each triangle listed in every cell
its bounding box touches), so a body vertex tests the few triangles of the cells its short probe crosses.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from tryon.sim.collision.cloth import fill_grid, tris_in_cells
from tryon.sim.collision.collider import BodyCollider
from tryon.sim.metrics import PENETRATION_TOLERANCE

# m: how deep under the skin the probe looks for the cloth. The thinnest parts the garments cover (a
# forearm, 5 cm across) are more than twice this, so the probe never reaches the cloth on the far side of
# the limb; a body poking through deeper than this reports this depth.
PROBE_IN = 0.02
# m: how far out from the skin the probe looks for a covering layer: cloth rests within a few mm of the
# skin where it touches; 2 cm keeps a sleeve hanging beside the torso from counting as the torso's cover.
PROBE_OUT = 0.02
# m: the grid's cell: about twice the shown meshes' edges (1-2 cm), so a triangle touches few cells.
GRID_CELL = 0.02


@njit(cache=True, nogil=True, inline="always")
def _line_hit(px, py, pz, dx, dy, dz, vertices, a0, a1, a2):
    """Where the line p + t d crosses triangle (a0, a1, a2) of ``vertices``: (t m, u, v: the weights of a1
    and a2), t NaN where it misses (or runs along the triangle's plane). Möller-Trumbore, both faces."""
    e1x = vertices[a1, 0] - vertices[a0, 0]
    e1y = vertices[a1, 1] - vertices[a0, 1]
    e1z = vertices[a1, 2] - vertices[a0, 2]
    e2x = vertices[a2, 0] - vertices[a0, 0]
    e2y = vertices[a2, 1] - vertices[a0, 1]
    e2z = vertices[a2, 2] - vertices[a0, 2]
    qx = dy * e2z - dz * e2y
    qy = dz * e2x - dx * e2z
    qz = dx * e2y - dy * e2x
    det = e1x * qx + e1y * qy + e1z * qz
    if abs(det) < 1e-14:
        return np.nan, 0.0, 0.0
    inv = 1.0 / det
    sx = px - vertices[a0, 0]
    sy = py - vertices[a0, 1]
    sz = pz - vertices[a0, 2]
    u = (sx * qx + sy * qy + sz * qz) * inv
    if u < 0.0 or u > 1.0:
        return np.nan, 0.0, 0.0
    rx = sy * e1z - sz * e1y
    ry = sz * e1x - sx * e1z
    rz = sx * e1y - sy * e1x
    v = (dx * rx + dy * ry + dz * rz) * inv
    if v < 0.0 or u + v > 1.0:
        return np.nan, 0.0, 0.0
    return (e2x * rx + e2y * ry + e2z * rz) * inv, u, v


@njit(cache=True, nogil=True)
def outermost_crossing(points, normals, t_in, t_out, vertices, faces, lo, cell, shape, cell_start, cell_tris):
    """For each point p (m, 3) m with unit normal n (m, 3): the largest t in [-t_in, t_out] m where the line
    p + t n crosses a triangle of the mesh (``vertices`` (n, 3) m, ``faces`` (f, 3)) listed in the grid
    (``collision.cloth.fill_grid``). Returns t (m,) float64, NaN where it crosses none, and the triangle crossed there
    (m,) int64, -1 for none."""
    out = np.full(points.shape[0], np.nan)
    tri = np.full(points.shape[0], -1, dtype=np.int64)
    r = np.empty(6, dtype=np.int64)
    seen = np.full(faces.shape[0], -1, dtype=np.int64)
    near = np.empty(faces.shape[0], dtype=np.int64)
    for i in range(points.shape[0]):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        dx, dy, dz = normals[i, 0], normals[i, 1], normals[i, 2]
        for a in range(3):
            s0 = points[i, a] - t_in * normals[i, a]
            s1 = points[i, a] + t_out * normals[i, a]
            r[2 * a] = max(int((min(s0, s1) - lo[a]) / cell), 0)
            r[2 * a + 1] = min(int((max(s0, s1) - lo[a]) / cell), shape[a] - 1)
        best = -np.inf
        for m in range(tris_in_cells(r, shape, cell_start, cell_tris, seen, i, near)):
            f = near[m]
            t = _line_hit(px, py, pz, dx, dy, dz, vertices, faces[f, 0], faces[f, 1], faces[f, 2])[0]
            if -t_in <= t <= t_out and t > best:  # NaN (a miss) compares False
                best = t
                tri[i] = f
        if best > -np.inf:
            out[i] = best
    return out, tri


@njit(cache=True, nogil=True)
def lift_triangles(points, normals, tri, vertices, faces, clearance):
    """Each point p (k, 3) m, with unit normal n (k, 3), lifts the triangle ``tri`` (k,) of ``faces`` over
    ``vertices`` (n, 3) m (in place) along n until the line p + t n crosses it at t = ``clearance`` m: the
    point-triangle constraint with the point fixed, C = t - clearance >= 0, corner k moving by
    b_k (clearance - t) / sum_j b_j^2 along n (b: the crossing's barycentric weights), which moves the crossing
    itself by exactly (clearance - t). The crossing is found again on the triangle as it is when the point's
    turn comes (an earlier point may have lifted it). Returns how many points lifted. Serial: points share
    triangles and triangles share corners."""
    lifted = 0
    for i in range(points.shape[0]):
        f = tri[i]
        a0, a1, a2 = faces[f, 0], faces[f, 1], faces[f, 2]
        t, u, v = _line_hit(points[i, 0], points[i, 1], points[i, 2], normals[i, 0], normals[i, 1], normals[i, 2],
                            vertices, a0, a1, a2)
        if not t < clearance:  # NaN: it slid off the line
            continue
        b0 = 1.0 - u - v
        scale = (clearance - t) / (b0 * b0 + u * u + v * v)
        for a in range(3):
            n = normals[i, a] * scale
            vertices[a0, a] += b0 * n
            vertices[a1, a] += u * n
            vertices[a2, a] += v * n
        lifted += 1
    return lifted


def _probe(collider: BodyCollider, parts: np.ndarray, garment: np.ndarray, faces: np.ndarray, t_in: float
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The body vertices the garment (``garment`` (n, 3) m, ``faces`` (f, 3)) may cover, on ``parts``, and the
    outermost cloth layer along each one's normal (``outermost_crossing`` up to ``t_in`` m under the skin,
    ``PROBE_OUT`` out): (near (q,) int64 body vertex indices, points (q, 3) m, normals (q, 3), t (q,) m,
    tri (q,) int64)."""
    body = collider.vertices
    empty = (np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros(0, dtype=np.int64))
    if len(faces) == 0:
        return empty
    reach = t_in + PROBE_OUT
    lo = garment.min(axis=0) - reach
    hi = garment.max(axis=0) + reach
    near = np.flatnonzero(np.all((body >= lo) & (body <= hi), axis=1)
                          & np.isin(collider.vertex_part, parts))
    if len(near) == 0:
        return empty
    shape = np.maximum(np.ceil((hi - lo) / GRID_CELL).astype(np.int64), 1)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    garment = np.ascontiguousarray(garment, dtype=np.float64)
    cell_start, cell_tris = fill_grid(garment, faces, lo, GRID_CELL, shape, 0.0)
    points = np.ascontiguousarray(body[near])
    normals = np.ascontiguousarray(collider.vertex_normals[near])
    t, tri = outermost_crossing(points, normals, t_in, PROBE_OUT, garment, faces, lo, GRID_CELL, shape, cell_start,
                                cell_tris)
    return near, points, normals, t, tri


def _shown(collider: BodyCollider, parts: np.ndarray, points: np.ndarray, under: np.ndarray) -> np.ndarray:
    """``under`` (indices into ``points`` (q, 3) m, body vertices) without the hidden skin: a body vertex
    inside another part (its own part puts it at ~0 depth) is not seen."""
    if len(under) == 0:
        return under
    return under[collider.depth(points[under], parts, offset=False) <= PENETRATION_TOLERANCE]


def show_through_depth(collider: BodyCollider, parts: np.ndarray, garment: np.ndarray,
                       faces: np.ndarray) -> np.ndarray:
    """(b,) m: for each vertex of the collider's current body, how far it pokes out through the shown
    garment (``garment`` (n, 3) m, ``faces`` (f, 3)) where the garment covers it (0 elsewhere, and for body
    vertices hidden inside another part); ``parts``: the body parts the garment was collided with (int64
    indices), the only ones it can cover. Measured up to PROBE_IN deep (see the module docstring)."""
    depth = np.zeros(len(collider.vertices))
    near, points, _, t, _ = _probe(collider, parts, garment, faces, PROBE_IN)
    keep = _shown(collider, parts, points, np.flatnonzero(t < -PENETRATION_TOLERANCE))  # NaN compares False
    depth[near[keep]] = -t[keep]
    return depth


def lift_over_skin(collider: BodyCollider, parts: np.ndarray, garment: np.ndarray, faces: np.ndarray,
                   clearance: float, deepest: float) -> int:
    """Mend what ``show_through_depth`` measures, in place: every body vertex whose outermost cloth layer lies
    under the skin lifts that triangle of ``garment`` (n, 3) m (``faces`` (f, 3)) along its normal until it
    crosses ``clearance`` m out (``lift_triangles``). A garment whose vertices are all outside the offset
    body can still cut under the skin between them: a long thin triangle over a shoulder's curve, a sleeve
    pulled tight over an elbow. Hidden skin (inside another part) lifts nothing. Returns how many body
    vertices lifted a triangle."""
    near, points, normals, t, tri = _probe(collider, parts, garment, faces, deepest)
    keep = _shown(collider, parts, points, np.flatnonzero(t < 0.0))
    if len(keep) == 0:
        return 0
    return int(lift_triangles(points[keep], normals[keep], tri[keep], garment,
                              np.ascontiguousarray(faces, dtype=np.int64), clearance))


def show_through_metrics(depth: np.ndarray) -> dict:
    """``body_through_vertices``: body vertices poking out through the cloth by more than 2 mm (the
    penetration tolerance, SPEC 7); ``max_body_through_mm``: the deepest, mm (at most PROBE_IN)."""
    return {
        "body_through_vertices": int((depth > PENETRATION_TOLERANCE).sum()),
        "max_body_through_mm": float(depth.max() * 1000.0) if len(depth) else 0.0,
    }
