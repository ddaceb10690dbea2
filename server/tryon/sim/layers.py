"""Layers: keeping an outfit's garments one over the other, on the simulated meshes and on the shown ones.

After each step the layers collide, innermost first, both ways (``collide_layers``): every point of an outer garment
that lies less than ``LAYER_GAP`` outside an inner garment's current coarse surface (or inside it) is moved to
``LAYER_GAP`` outside it, and every point of the inner garment through the outer one's surface back under it; the
triangle takes its share of each move by inverse mass (``collision.cloth.push_outside_layer``: the point-triangle
constraint of position-based dynamics), but the inner garment's points on the body do not give way (the body is
under them; pushed in, the body would push them back out along its normal, up the hips' slope: a skirt's band under
a long-sleeve's hem climbed that way), so the outer garment takes the whole move there. An outer point pushed gets
a contact plane on the inner garment (``DrapeState.layer_planes``), which the next step takes instead of the body's
where it asks more (``contacts.take_stricter_planes``): the substeps keep the point on the garment under it, not on
the body it would fall back to between two layer collisions (a T-shirt under a long-sleeve, both M, fought like
that every step and never came to rest). Only pushed points: planes also for the points lying within the body's
``near`` beyond the gap left a T-shirt's hem dipping 2 cm under a skirt at the back (the planes are a step old when
taken, and the skirt's flare had moved). Which side is outside is fixed by the layer order and the body, not by the
files' winding: each face's normal is turned away from the nearest body axis, by its own vote, every step
(``outward_from_body``, ``collision.cloth.face_sides``). A one-sided push with a kept layer order is what Houdini
Vellum and CLO do for layered garments; it needs no history and untangles two layers that started crossed (an outer
garment aligned partly inside the inner one ends outside it), which a side-keeping test would lock in.

Skip what the scene does not need: only the outer points inside an inner garment's box (plus ``LAYER_REACH``) are
tested, through a grid of the inner triangles within reach of their box.

The shown meshes are built innermost first, each outer one kept ``SHOWN_LAYER_GAP`` off the finished shown meshes
under it inside its own building (``off_shown``: ``full_mesh.follow_coarse``'s ``also_collide``,
``collision.over_fixed``): after the body collision of each of its rounds, so that the next round's stretch passes
carry a push to the pushed point's neighbours as they carry the body's. The coarse layers ``LAYER_GAP`` apart are not
enough for the shown ones: a shown mesh bulges out of its coarse triangles' chords (it is pushed out of the body
between the coarse points), the one under it as much as the one over it. Pushed once at the end instead, with no
stretch passes after the pushes, the hems of the outer garments over a flared skirt crumpled into spikes, and more
stayed through (the 36 top-over-bottom outfits of ``tryon bench --only outfits``: 371 layer-penetrating vertices
that way, 130 this way). ``layer_metrics`` counts what is still more than ``LAYER_TOLERANCE`` on the body's side of a
garment under it, each triangle's outward side taken on the shown meshes as they end.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from tryon.body.types import Body
from tryon.sim.collision.cloth import (
    build_tri_grid, face_sides, outward_from_axes, overlap, push_layer, signed_face_normals,
)
from tryon.sim.collision.crossings import layer_depths
from tryon.sim.collision.over_fixed import OverFixed

# m: how far outside an inner garment's coarse surface an outer garment's coarse points are kept: about two
# cloth thicknesses. Not more: a waistband over a tucked-in shirt grows by 2 pi x this (1.6 cm on an 82 cm
# waist at 2.5 mm, 2 % of it: the band's own stretch limit). Where the coarse triangles sag between their
# points, the shown meshes are kept apart as they are built (``SHOWN_LAYER_GAP``).
LAYER_GAP = 0.0025
# m: the most a layer collision moves a point in one step: garments aligned each on its own may start
# centimetres into each other (a trouser waistband inside a loose shirt's hem); they come apart over a few
# steps, their springs following, instead of in one jump.
LAYER_MAX_PUSH = 0.005
# m: an outer point further than this from every inner triangle is not tested (the grid's reach).
LAYER_REACH = 0.03
# m: the inner triangles' grid cell (about the coarse edge length).
LAYER_CELL = 0.03
# m: how far outside the inner shown meshes the outer shown meshes are put.
SHOWN_LAYER_GAP = 0.0015
# m: the most one push of the shown meshes moves a vertex in a round (``SHOWN_LAYER_ROUNDS``). Unbounded, they
# ran away where an outer hem meets a flared inner garment: the hem's triangles pushed out along their tilted
# normals lay over more of the inner cloth each round, and grew spikes. 6 mm x 5 rounds reach as deep as the
# layers' reach (30 mm) in half the rounds of 3 mm x 10, as well (the 39 outfits of ``tryon bench --only
# outfits``: 130 + 51 layer-penetrating vertices, against 136 + 50) and with hems as smooth.
SHOWN_MAX_PUSH = 0.006
# Pushes of the outer shown meshes off the inner ones in one ``also_collide`` call (each round moves only the
# points still too close).
SHOWN_LAYER_ROUNDS = 5
# m: a shown vertex of an outer garment more than this on the body's side of a garment under it is a layer
# penetration (issue 29's tolerance, as for the body).
LAYER_TOLERANCE = 0.002


def outward_from_body(points: np.ndarray, body: Body) -> np.ndarray:
    """(k, 3) unit directions away from the body at ``points`` (k, 3) m: from the nearest point of the nearest
    body part's axis segment (``body.part_axes``) to the point."""
    return outward_from_axes(np.ascontiguousarray(points, dtype=np.float64), body.part_axes)


def collide_layers(points: list[np.ndarray], prev: list[np.ndarray], inv_mass: list[np.ndarray],
                   faces: list[np.ndarray], sides: list[np.ndarray], gap: float, near: float = 0.0,
                   planes: list[tuple] | None = None, max_push: float = np.inf,
                   pressed: list[np.ndarray] | None = None, both_ways: bool = False,
                   reach: float = None, on_body: list[np.ndarray] | None = None) -> int:
    """Keep the layers (``points[i]`` (k_i, 3) m, in place, innermost first; triangles ``faces[i]`` (f_i, 3) int64,
    turned outward by ``sides[i]`` (f_i,), ``face_sides``) ``gap`` m apart: every outer layer's points outside
    each layer under it, and with ``both_ways`` also every inner layer's points under each layer over it (a point
    of the shirt between two points of the trousers over it: vertices against triangles catch only one of the
    two). Corrections are shared by inverse mass (``inv_mass``: all zero for a layer that must not move);
    ``prev``: each layer's previous positions, moved with it; ``planes``: each layer's contact planes
    (``DrapeState.planes``), where an outer point pushed, or within ``near`` m beyond ``gap``, gets the layer's
    plane (an inner point keeps its plane on the body); None: none kept. ``max_push`` m: the most a point moves
    in one call; ``pressed``: per layer (k_i,) bool out, its points an outer layer pressed on; ``reach`` m: how
    far from a layer its grid finds points (default ``LAYER_REACH``). Only the triangles within ``reach`` of the
    other layer's box are binned (a shirt's hem over trousers: the trousers' hips, not their legs). Returns how
    many points were pushed. ``on_body``: per layer (k_i,) bool, its points on the body (with a contact plane):
    the inner layer's such points do not give way to an outer one (the body is under them), the outer one takes
    the whole move; pushed in, they would be pushed back out along the body's normal, up a slope."""
    reach = LAYER_REACH if reach is None else reach

    def push(mover: int, under: int, sign: float, keep_planes: bool) -> int:
        mover_mass, under_mass = inv_mass[mover], inv_mass[under]
        if on_body is not None:  # the layer nearer the body gives way only where the body is not under it
            if sign > 0.0:
                under_mass = np.where(on_body[under], 0.0, under_mass)
            else:
                mover_mass = np.where(on_body[mover], 0.0, mover_mass)
        active, close = overlap(points[mover], points[under], faces[under], reach)
        if not active.any():
            return 0
        tris = np.ascontiguousarray(faces[under][close])
        normals = signed_face_normals(points[under], tris, sign * sides[under][close])
        grid = build_tri_grid(points[under], tris, LAYER_CELL, reach)
        return push_layer(points[mover], prev[mover], mover_mass, active, points[under], prev[under],
                          under_mass, tris, normals, grid, gap, reach, near,
                          planes[mover] if keep_planes and planes is not None else None, max_push,
                          pressed[under] if keep_planes and pressed is not None else None)

    pushed = 0
    for i in range(len(points) - 1):
        for j in range(i + 1, len(points)):
            pushed += push(j, i, 1.0, True)  # the outer layer's points outside the inner one
            if both_ways:
                pushed += push(i, j, -1.0, False)  # the inner layer's points under the outer one
    return pushed


def off_shown(under: list[np.ndarray], faces: list[np.ndarray], body: Body) -> Callable[[np.ndarray, np.ndarray], int]:
    """``follow_coarse``'s ``also_collide`` for an outer garment's shown mesh: kept ``SHOWN_LAYER_GAP`` off the
    shown meshes ``under`` it (each (n_i, 3) m, held still; triangles ``faces``, the outer garment's last), both
    ways, at most ``SHOWN_MAX_PUSH`` a round, up to ``SHOWN_LAYER_ROUNDS`` rounds (``collision.over_fixed``)."""
    fixed = OverFixed([(v, f, face_sides(v, f, outward_from_body(v, body))) for v, f in zip(under, faces)],
                      faces[-1], SHOWN_LAYER_GAP, SHOWN_MAX_PUSH, SHOWN_LAYER_ROUNDS, LAYER_REACH, LAYER_CELL)

    def collide(x: np.ndarray, x_prev: np.ndarray, moved: np.ndarray | None = None) -> int:
        return fixed.push(x, x_prev, face_sides(x, faces[-1], outward_from_body(x, body)), moved)
    return collide


def layer_metrics(shown: list[np.ndarray], faces: list[np.ndarray], sides: list[np.ndarray]) -> tuple[int, float]:
    """Over the shown meshes of the layers (``shown`` (n_i, 3) m, innermost first, triangles ``faces`` turned
    outward by ``sides``, ``face_sides``): the
    vertices more than ``LAYER_TOLERANCE`` on the wrong side of another garment where they overlap (an outer
    garment's on the body's side of one under it, an inner garment's outside one over it), each counted once,
    and the deepest, m."""
    normals = [signed_face_normals(s, f, side) for s, f, side in zip(shown, faces, sides)]
    count, deepest = 0, 0.0
    for k in range(len(shown)):
        worst = np.zeros(len(shown[k]))
        for other in range(len(shown)):
            if other != k:
                sign = 1.0 if other < k else -1.0  # under it: stay outside; over it: stay under
                worst = np.maximum(worst, layer_depths(shown[k], shown[other], faces[other], sign * normals[other],
                                                       LAYER_REACH))
        count += int(np.count_nonzero(worst > LAYER_TOLERANCE))
        deepest = max(deepest, float(worst.max()) if len(worst) else 0.0)
    return count, deepest
