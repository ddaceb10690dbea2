"""Cloth that passed through itself taken back out: intersection-contour minimisation (Volino and
Magnenat-Thalmann 2006, "Resolving surface collisions through intersection contour minimization").

Where a garment's surface passes through itself, its triangles meet along closed or open curves, the
intersection contours. Shrinking a contour to nothing separates the two sheets, whichever sheet was on which
side before: no history is needed, so cloth that arrives tangled (a fold the step's moves pushed through, the
two legs of wide trousers meeting below the crotch) comes apart over a few rounds instead of staying locked in.
Each crossing of an edge through a triangle is a point of a contour; the contour there shortens fastest when the
edge moves against the triangle along ``contour_gradient``. A round (``untangle_round``) finds every crossing on a
grid of the triangles (``crossings.find_crossings``: the cost follows the mesh, ~1.5 ms for a catalogue
garment's coarse mesh) and moves each crossing edge's ends at most ``Tuning.untangle_step`` along it, the
triangle's corners the opposite way, shared by inverse mass; x_prev moves with x (no velocity from the move).

Where it runs: in the rounds of the shown mesh's rebuild but the last (``full_mesh.follow_coarse``, before their
stretch passes and collision), up to ``Tuning.shown_untangle_rounds`` rounds each until one finds no crossing
(``untangle_mesh``: after the first, a round looks only where points moved). On the simulated mesh too if
``Tuning.untangle_every`` asks (every so many steps once the body is complete, and in the relaxation while it
makes progress; see ``Tuning`` for why not by default), a point held pinched between two body parts or on the
body (or on an outfit's layer) staying where it is. What it cannot undo is cloth the body holds crossed (pressed
between the thighs, on the floor): there it fights the springs.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
from numba import njit

from tryon.sim.collision.cloth import build_tri_grid
from tryon.sim.collision.crossings import find_crossings


@njit(cache=True, nogil=True, inline="always")
def _unit_normal(x, a, b, c):
    e1 = x[b] - x[a]
    e2 = x[c] - x[a]
    n = np.cross(e1, e2)
    ln = math.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
    return n / ln if ln > 1e-18 else n


@njit(cache=True, nogil=True)
def contour_gradient(x, i, j, face, adjacent, faces):
    """(3,): the direction the edge ``i``-``j`` should move relative to triangle ``face`` (its corners moving the
    other way) to shorten their intersection contour fastest, summed over the edge's triangles ``adjacent``
    (2,) int64 (-1: none). For the contour segment in an adjacent triangle, from the crossing point P along
    the line the two triangles' planes share (unit R, into that triangle): moving the edge by d moves P by
    d - (N.d) / (N.E) E (N the crossed triangle's normal, E = x_j - x_i), which shortens the segment by
    R.d - (R.E)(N.d) / (N.E); the gradient of that is R - (R.E) / (N.E) N."""
    nt = _unit_normal(x, faces[face, 0], faces[face, 1], faces[face, 2])
    e = x[j] - x[i]
    en = e[0] * nt[0] + e[1] * nt[1] + e[2] * nt[2]
    g = np.zeros(3)
    if abs(en) < 1e-12:
        return g
    for k in range(2):
        t = adjacent[k]
        if t < 0:
            continue
        ni = _unit_normal(x, faces[t, 0], faces[t, 1], faces[t, 2])
        r = np.cross(nt, ni)
        lr = math.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
        if lr < 1e-9:
            continue
        r /= lr
        # into triangle t: toward its corner off the edge, across the edge
        o = faces[t, 0] + faces[t, 1] + faces[t, 2] - i - j
        into = x[o] - x[i]
        into -= ((into[0] * e[0] + into[1] * e[1] + into[2] * e[2]) / (e[0] * e[0] + e[1] * e[1] + e[2] * e[2])) * e
        if r[0] * into[0] + r[1] * into[1] + r[2] * into[2] < 0.0:
            r = -r
        re = r[0] * e[0] + r[1] * e[1] + r[2] * e[2]
        g += r - (re / en) * nt
    return g


@njit(cache=True, nogil=True)
def _contour_moves(x, inv_mass, edges, adjacent, faces, hits, n_hits, step, move, weight):
    """Each crossing's bounded move (``step`` m, less where its gradient is small) summed into ``move`` (k, 3)
    and the number of crossings a point takes part in into ``weight`` (k,). Serial."""
    for h in range(n_hits):
        e, f = hits[h, 0], hits[h, 1]
        i, j = edges[e, 0], edges[e, 1]
        g = contour_gradient(x, i, j, f, adjacent[e], faces)
        lg = math.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2])
        if lg < 1e-12:
            continue
        g *= step / math.sqrt(lg * lg + 1.0)
        w_edge = inv_mass[i] + inv_mass[j]
        w_face = inv_mass[faces[f, 0]] + inv_mass[faces[f, 1]] + inv_mass[faces[f, 2]]
        if w_edge + w_face <= 0.0:
            continue
        # the relative move 2 g shared by inverse mass: the edge takes w_edge / total of it
        s_edge = 2.0 * w_edge / (w_edge + w_face)
        s_face = 2.0 * w_face / (w_edge + w_face)
        for v in (i, j):
            if inv_mass[v] > 0.0:
                move[v] += s_edge * g
                weight[v] += 1.0
        for c in range(3):
            v = faces[f, c]
            if inv_mass[v] > 0.0:
                move[v] -= s_face * g
                weight[v] += 1.0


def untangle_round(x: np.ndarray, x_prev: np.ndarray, inv_mass: np.ndarray, faces: np.ndarray, edges: np.ndarray,
                   adjacent: np.ndarray, step: float, cell: float = 0.03) -> int:
    """One round of contour minimisation of the mesh ``x`` (k, 3) m, triangles ``faces`` (f, 3) int64, ``edges``
    (e, 2) int64 with their triangles ``adjacent`` (``topology.edge_faces``), in place: every point of a crossing
    moves at most ``step`` m (the mean of its crossings' moves), ``x_prev`` with it (no velocity from the move);
    points of zero ``inv_mass`` stay. Returns the number of crossings found before the move."""
    return untangle_mesh(x, x_prev, inv_mass, faces, edges, adjacent, step, 1, cell)


def _move(x: np.ndarray, x_prev: np.ndarray, inv_mass: np.ndarray, faces: np.ndarray, edges: np.ndarray,
          adjacent: np.ndarray, hits: np.ndarray, step: float) -> None:
    """Move the points of the crossings ``hits`` (c, 2) (edge, triangle), each by the mean of its crossings'
    moves, x_prev with x."""
    move = np.zeros_like(x)
    weight = np.zeros(len(x))
    _contour_moves(x, inv_mass, edges, adjacent, faces, hits, len(hits), float(step), move, weight)
    moved = weight > 0
    move[moved] /= weight[moved, None]
    x += move
    x_prev += move


def untangle_mesh(x: np.ndarray, x_prev: np.ndarray, inv_mass: np.ndarray, faces: np.ndarray, edges: np.ndarray,
                  adjacent: np.ndarray, step: float, rounds: int, cell: float = 0.03,
                  after: Callable[[np.ndarray, np.ndarray, np.ndarray], object] | None = None) -> int:
    """Rounds of contour minimisation (each as ``untangle_round``) on the mesh ``x`` (k, 3) m in place, at most
    ``rounds``, until one finds no crossing; ``after(x, x_prev, moved)`` after each round's move, ``moved`` (k,)
    bool the points it moved (an outfit's push off the layers under it). After the first, a round looks for
    crossings only where a point moved since the last look (``_crossings_after``): the same pairs as a whole
    search, for a fraction of its cost. Returns the crossings the last look found."""
    hits = _all_crossings(x, faces, edges, cell)
    for r in range(rounds):
        if len(hits) == 0:
            return 0
        last = r == rounds - 1
        before = x.copy() if after is not None or not last else None
        _move(x, x_prev, inv_mass, faces, edges, adjacent, hits, step)
        if after is not None:
            after(x, x_prev, np.any(x != before, axis=1))
        if not last:
            hits = _crossings_after(x, faces, edges, cell, np.any(x != before, axis=1), hits)
    return len(hits)


def _all_crossings(x: np.ndarray, faces: np.ndarray, edges: np.ndarray, cell: float) -> np.ndarray:
    """(c, 2) int64 (edge, triangle): every crossing of the mesh, found on a grid of all its triangles."""
    return find_crossings(x, edges, faces, build_tri_grid(x, faces, cell, 0.0), capacity=max(64, len(edges) // 4))


def _crossings_after(x: np.ndarray, faces: np.ndarray, edges: np.ndarray, cell: float, moved: np.ndarray,
                     previous: np.ndarray) -> np.ndarray:
    """The crossings of the mesh ``x`` after its points ``moved`` (k,) bool did, ``previous`` (c, 2) the ones
    before: whether an edge crosses a triangle changes only if one of their five points moved, so the previous
    pairs with none moved stay, the moved edges are tested against every triangle and the others against the
    triangles with a moved corner. The three sets are disjoint: no pair is counted twice."""
    edge_moved = moved[edges].any(axis=1)
    face_moved = moved[faces].any(axis=1)
    found = [previous[~edge_moved[previous[:, 0]] & ~face_moved[previous[:, 1]]]]
    moved_edges = np.flatnonzero(edge_moved)
    if len(moved_edges):
        hits = _all_crossings(x, faces, np.ascontiguousarray(edges[moved_edges]), cell)
        hits[:, 0] = moved_edges[hits[:, 0]]
        found.append(hits)
    moved_faces = np.flatnonzero(face_moved)
    still_edges = np.flatnonzero(~edge_moved)
    if len(moved_faces) and len(still_edges):
        hits = _all_crossings(x, np.ascontiguousarray(faces[moved_faces]), np.ascontiguousarray(edges[still_edges]),
                              cell)
        hits[:, 0] = still_edges[hits[:, 0]]
        hits[:, 1] = moved_faces[hits[:, 1]]
        found.append(hits)
    return np.concatenate(found)


def untangle(model, state) -> int:
    """One round of ``untangle_round`` on a drape's simulated mesh (``state.x``; ``model``: its
    ``state.DrapeModel``), ``model.tuning.untangle_step`` m at most."""
    faces, edges, adjacent = model.garment.coarse_edge_faces
    # a point on the body or on the garment under it (an outfit's layer) stays where they hold it, as does one held
    # in a pinch between two body parts
    w = np.where(state.held | state.has_plane | state.layer_has, 0.0, state.inv_mass)
    return untangle_round(state.x, state.x_prev, w, faces, edges, adjacent, model.tuning.untangle_step)
