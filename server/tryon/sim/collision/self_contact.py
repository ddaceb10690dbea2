"""Cloth on its own cloth (issue 53 item 1): at the end of a step (and of each relaxation round) every pair of the
simulated mesh that passed through each other within it goes back to its side, and every pair on its side
nearer than a thickness is pushed apart to it.

A pair is a point and a triangle it is not a corner of, or two edges that share no end (``ccd``: both are needed;
two surfaces crossing at an angle pass edge through edge with no point through a triangle). Its side is the one
it was on before the first crossing of the step, or the one it ends on when it did not cross (a point that went
round a triangle's edge is rightly on its other side; a mesh that began the step crossed is left as crossed: the
untangling's work). The push is a position-based constraint along the triangle's normal (or the two edges'
common normal), shared by inverse mass and barycentric weight; it takes the pushed point's velocity into the
triangle away, so a contact feeds no energy into the next step. Gauss-Seidel passes over the pairs
(``contact_pairs.SelfContact``) until one pushes nothing, at most ``tuning.self_passes``; what is still crossed then
goes back to where the step began, with what it crossed, until nothing is: so a mesh that begins a step without
crossings ends it without, as far as straight paths tell.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tryon.garment.topology import face_edge_ids
from tryon.sim.collision.ccd import (
    closest_on_segments, event_side, far_from_edge, far_from_triangle, over_triangle, paths_apart, unit_normal,
)
from tryon.sim.collision.contact_pairs import SelfContact

# rounds of putting back what still crosses after the passes; past them the whole mesh goes back to where the step
# began (no point has moved, so nothing can have crossed)
ROLLBACK_ROUNDS = 50


@njit(cache=True, nogil=True)
def _contact(i, f, x, x0, faces, thickness):
    """The push point i needs against triangle f as every point moved from x0 to x (n, 3) m: (unit normal, depth
    m > 0, u, v of the closest point, whether it passed through the triangle), depth 0 when none. A contact is a
    point that passed through the triangle (``ccd.event_side``) or lies over it less than ``thickness`` off it;
    the normal is the triangle's winding normal at the end, turned to the side the point belongs on."""
    a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
    nx, ny, nz, ok = unit_normal(x, a, b, c)
    if not ok:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    side, crossed = event_side(i, a, b, a, c, x, x0, True)
    nx, ny, nz = side * nx, side * ny, side * nz
    px, py, pz = x[i, 0], x[i, 1], x[i, 2]
    s1 = (px - x[a, 0]) * nx + (py - x[a, 1]) * ny + (pz - x[a, 2]) * nz  # > 0 on the side it belongs on
    if s1 >= thickness:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    u, v, over = over_triangle(px, py, pz, x, a, b, c, nx, ny, nz)
    if not (crossed or over):
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    return nx, ny, nz, thickness - s1, u, v, crossed


@njit(cache=True, nogil=True)
def _push(i, f, x, x_prev, w, faces, nx, ny, nz, depth, u, v):
    """Push point i and the corners of triangle f apart by ``depth`` m along n (toward i's side), by inverse mass
    and barycentric weight; i's velocity into the triangle goes."""
    a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
    ba, bb, bc = 1.0 - u - v, u, v
    den = w[i] + w[a] * ba * ba + w[b] * bb * bb + w[c] * bc * bc
    if den <= 0.0:
        return False
    lam = depth / den
    vi = (x[i, 0] - x_prev[i, 0]) * nx + (x[i, 1] - x_prev[i, 1]) * ny + (x[i, 2] - x_prev[i, 2]) * nz
    inward = min(vi, 0.0)
    move = w[i] * lam
    for k, wk in ((a, w[a] * ba * lam), (b, w[b] * bb * lam), (c, w[c] * bc * lam)):
        x[k, 0] -= wk * nx
        x[k, 1] -= wk * ny
        x[k, 2] -= wk * nz
        x_prev[k, 0] -= wk * nx
        x_prev[k, 1] -= wk * ny
        x_prev[k, 2] -= wk * nz
    x[i, 0] += move * nx
    x[i, 1] += move * ny
    x[i, 2] += move * nz
    if w[i] > 0.0:
        x_prev[i, 0] += (move + inward) * nx
        x_prev[i, 1] += (move + inward) * ny
        x_prev[i, 2] += (move + inward) * nz
    return True


@njit(cache=True, nogil=True)
def _edge_contact(p1, p2, q1, q2, x, x0, thickness):
    """The push edges (p1, p2) and (q1, q2) need as every point moved from x0 to x (n, 3) m: (unit normal toward q's
    side, depth m > 0, s, t the closest points' parameters, whether they passed through each other), depth 0 when
    none. A contact is a pair that passed through each other (``ccd.event_side``) or whose closest points, both
    inside their segments (at an end, the point-triangle test has it), are less than ``thickness`` apart on their
    side; the normal is the two edges' common normal at the end."""
    d1x, d1y, d1z = x[p2, 0] - x[p1, 0], x[p2, 1] - x[p1, 1], x[p2, 2] - x[p1, 2]
    d2x, d2y, d2z = x[q2, 0] - x[q1, 0], x[q2, 1] - x[q1, 1], x[q2, 2] - x[q1, 2]
    nx, ny, nz = d1y * d2z - d1z * d2y, d1z * d2x - d1x * d2z, d1x * d2y - d1y * d2x
    ln = math.sqrt(nx * nx + ny * ny + nz * nz)
    if ln < 1e-12:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False  # parallel: no crossing between them that a point's test misses
    side, crossed = event_side(q1, p1, p2, q1, q2, x, x0, False)
    nx, ny, nz = nx * side / ln, ny * side / ln, nz * side / ln
    s, t = closest_on_segments(x, p1, p2, q1, q2)
    gap = ((x[q1, 0] + t * d2x - x[p1, 0] - s * d1x) * nx + (x[q1, 1] + t * d2y - x[p1, 1] - s * d1y) * ny
           + (x[q1, 2] + t * d2z - x[p1, 2] - s * d1z) * nz)  # > 0 on the side they belong on
    if gap >= thickness:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    if not crossed and (s <= 0.0 or s >= 1.0 or t <= 0.0 or t >= 1.0):
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    s = min(1.0, max(0.0, s))
    t = min(1.0, max(0.0, t))
    return nx, ny, nz, thickness - gap, s, t, crossed


@njit(cache=True, nogil=True)
def _push_edges(p1, p2, q1, q2, x, x_prev, w, nx, ny, nz, depth, s, t):
    """Push edge (q1, q2) along n and edge (p1, p2) against it until their closest points (parameters s, t) are
    ``depth`` m further apart, by inverse mass and weight; the previous positions move with them."""
    bp1, bp2, bq1, bq2 = 1.0 - s, s, 1.0 - t, t
    den = w[p1] * bp1 * bp1 + w[p2] * bp2 * bp2 + w[q1] * bq1 * bq1 + w[q2] * bq2 * bq2
    if den <= 0.0:
        return False
    lam = depth / den
    for k, m in ((p1, -w[p1] * bp1 * lam), (p2, -w[p2] * bp2 * lam), (q1, w[q1] * bq1 * lam),
                 (q2, w[q2] * bq2 * lam)):
        x[k, 0] += m * nx
        x[k, 1] += m * ny
        x[k, 2] += m * nz
        x_prev[k, 0] += m * nx
        x_prev[k, 1] += m * ny
        x_prev[k, 2] += m * nz
    return True


@njit(cache=True, nogil=True)
def _contact_pass(x, x_prev, x0, w, faces, edges, points, edge_pairs, thickness, crossed, touched, touching):
    """One Gauss-Seidel pass over the listed (point, triangle) ``points`` (p, 2) and ``edge_pairs`` (q, 2) int64;
    returns how many it pushed. With ``crossed`` (n,) bool given non-empty, nothing is pushed: the points of
    every pair that crossed within the step are marked there and counted. Serial: points are shared between
    pairs.

    ``touched`` (n,) bool, if not empty: only pairs with a point marked there are tested (the points the previous
    pass pushed or counted: a pair none of whose points moved since it was tested and found apart is apart still).
    ``touching`` (n,) bool: every point of a pair this pass pushes or counts is marked in it."""
    pushed = 0
    marking = len(crossed) > 0
    some = len(touched) > 0
    for k in range(points.shape[0]):
        i, f = points[k, 0], points[k, 1]
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        if some and not (touched[i] or touched[a] or touched[b] or touched[c]):
            continue
        if paths_apart(x, x0, i, i, i, a, b, c, thickness) or far_from_triangle(i, f, x, x0, faces, thickness):
            continue
        nx, ny, nz, depth, u, v, through = _contact(i, f, x, x0, faces, thickness)
        if marking:
            if through:
                crossed[i] = crossed[a] = crossed[b] = crossed[c] = True
                pushed += 1
        elif depth > 0.0 and (_push(i, f, x, x_prev, w, faces, nx, ny, nz, depth, u, v) or through):
            pushed += 1  # a crossed pair that cannot move (held) counts: the check after the passes takes it
            touching[i] = touching[a] = touching[b] = touching[c] = True
    for k in range(edge_pairs.shape[0]):
        p1, p2 = edges[edge_pairs[k, 0], 0], edges[edge_pairs[k, 0], 1]
        q1, q2 = edges[edge_pairs[k, 1], 0], edges[edge_pairs[k, 1], 1]
        if some and not (touched[p1] or touched[p2] or touched[q1] or touched[q2]):
            continue
        if paths_apart(x, x0, p1, p2, p2, q1, q2, q2, thickness) or far_from_edge(p1, p2, q1, q2, x, x0, thickness):
            continue
        nx, ny, nz, depth, s, t, through = _edge_contact(p1, p2, q1, q2, x, x0, thickness)
        if marking:
            if through:
                crossed[p1] = crossed[p2] = crossed[q1] = crossed[q2] = True
                pushed += 1
        elif depth > 0.0 and (_push_edges(p1, p2, q1, q2, x, x_prev, w, nx, ny, nz, depth, s, t) or through):
            pushed += 1
            touching[p1] = touching[p2] = touching[q1] = touching[q2] = True
    return pushed


def keep_sides(contacts: SelfContact, x: np.ndarray, x_prev: np.ndarray, x0: np.ndarray, w: np.ndarray,
               thickness: float, passes: int) -> int:
    """Keep every point of x (n, 3) m on its side (``event_side``) of each triangle of the mesh near it, and every
    edge of each edge near it, as they moved from x0 (n, 3) m (where the step began), at least ``thickness`` m
    off, in at most ``passes`` Gauss-Seidel passes (fewer once one pushes nothing); then what is still crossed
    goes back to where the step began, with what crossed it, until nothing crosses. w (n,) 1/kg: the inverse
    masses the pushes share by (0: held where it is). x_prev (n, 3) moves with x. Returns the contacts pushed."""
    total = 0
    no_marks = np.zeros(0, dtype=np.bool_)
    crossed = np.zeros(len(x), dtype=np.bool_)
    touched, touching = np.zeros(0, dtype=np.bool_), np.zeros(len(x), dtype=np.bool_)
    contacts.update(x, x0)
    for _ in range(passes):
        pushed = _contact_pass(x, x_prev, x0, w, contacts.faces, contacts.edges, contacts.points,
                               contacts.edge_pairs, float(thickness), no_marks, touched, touching)
        total += pushed
        if pushed == 0:
            break
        touched, touching = touching, (touched if len(touched) else np.zeros(len(x), dtype=np.bool_))
        touching[:] = False
    if total == 0:
        return total
    # the passes may have moved a point out of the list's reach, or bent a piece it left out as flat
    if contacts.update(x, x0, from_start=False):
        touched = no_marks  # new pairs: every pair is tested
    elif pushed == 0:
        return total
    for _ in range(ROLLBACK_ROUNDS):
        if not _contact_pass(x, x_prev, x0, w, contacts.faces, contacts.edges, contacts.points, contacts.edge_pairs,
                             float(thickness), crossed, touched, touching):
            return total
        touched = no_marks  # after a roll back, every pair
        x[crossed] = x0[crossed]
        x_prev[crossed] = x0[crossed]
        crossed[:] = False
    x[:] = x0  # still crossed after that many rounds: the whole step back
    x_prev[:] = x0
    return total


def keep_drape_sides(model, state, x0: np.ndarray, w: np.ndarray) -> int:
    """``keep_sides`` on a drape's simulated mesh (``state.x``; ``model``: its ``state.DrapeModel``) as it moved
    from x0 (n, 3) m, with the inverse masses w (n,) 1/kg, its pairs kept in the state (``state.self_contact``)
    from call to call."""
    tu = model.tuning
    if state.self_contact is None:
        faces = np.ascontiguousarray(model.garment.coarse_faces, dtype=np.int64)
        edges, face_edges = face_edge_ids(faces)
        state.self_contact = SelfContact(faces, edges, face_edges, tu.self_thickness,
                                         tu.self_thickness + tu.self_margin)
    return keep_sides(state.self_contact, state.x, state.x_prev, x0, w, tu.self_thickness, tu.self_passes)
