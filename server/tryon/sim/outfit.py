"""An outfit: up to three garments draped at once, each over the ones under it (issue 29).

Method. Every garment is its own drape (``start``, ``step``, ``relax``: its springs, its contacts with the body,
its own start-up), stepped in lockstep; after each step the layers collide, innermost first, both ways: every point
of an outer garment that lies less than ``LAYER_GAP`` outside an inner garment's current coarse surface (or inside
it) is moved to ``LAYER_GAP`` outside it, and every point of the inner garment through the outer one's surface back
under it; the triangle takes its share of each move by inverse mass (``collision.cloth.push_outside_layer``: the
point-triangle constraint of position-based dynamics), but the inner garment's points on the body do not give way
(the body is under them; pushed in, the body would push them back out along its normal, up the hips' slope: a
skirt's band under a long-sleeve's hem climbed that way), so the outer garment takes the whole move there.
An outer point pushed gets a contact plane on the inner garment (``DrapeState.layer_planes``), which the next step
takes instead of the body's where it asks more (``contacts.take_stricter_planes``): the substeps keep the point on
the garment under it, not on the body it would fall back to between two layer collisions (a T-shirt under a
long-sleeve, both M, fought like that every step and never came to rest). Only pushed points: planes also for the
points lying within the body's ``near`` beyond the gap left a T-shirt's hem dipping 2 cm under a skirt at the back
(the planes are a step old when taken, and the skirt's flare had moved). Which side is outside is fixed by the
layer order and the body, not by the files' winding: each face's normal is turned away from the nearest body axis,
by its own vote, every step (``outward_from_body``, ``collision.cloth.face_sides``). A one-sided push with a kept
layer order is what Houdini Vellum and CLO do for layered garments; it needs no history and untangles two layers
that started crossed (an outer garment aligned partly inside the inner one ends outside it), which a side-keeping
test would lock in. The layers collide only once every garment's start-up is over (each drape grows the body and
turns the arms on its own schedule), on the body all garments share.

Both cores: the garments' steps (and their relaxations) touch only their own drape, and the
kernels release the GIL, so where the calling thread may use two threads (``numba.get_num_threads``: the
service's pool gives a try-on running alone both cores) they run at once, one garment a thread (each on one
thread of its own), the same numbers as one after the other.

Skip what the scene does not need: only the outer points inside an inner garment's box (plus ``LAYER_REACH``)
are tested, through a grid of the inner triangles within reach of their box; a garment at rest that no layer pushed is not stepped
(it sleeps until a push moves it by more than ``tuning.rest_move``).

The end: each garment relaxes on its own, then ``FINAL_LAYER_ROUNDS`` rounds of the layers' collision, each
followed by one relaxation round of every garment (``relax.relaxation_round``: its over-long springs back to their
limits, a point the layers pushed held on the layer under it by that layer's plane as in the steps) and the body
collision (nothing through the body either). Pushed off the layer under it with no springs after the push, an
outer garment was left with springs far over their limits where it lay over the inner one's folds (a T-shirt S
over trousers M, both advised for 170 / 92 / 76 / 98: a back spring at 43 %, "too tight at the hips"). Then the
shown meshes are built innermost first, each
outer one kept ``SHOWN_LAYER_GAP`` off the finished shown meshes under it inside its own building
(``full_mesh.follow_coarse``'s ``also_collide``, ``collision.over_fixed``): after the body collision of each of its
rounds, so that the next round's stretch passes carry a push to the pushed point's neighbours as they carry the
body's. The coarse layers ``LAYER_GAP`` apart are not enough for the shown ones: a shown mesh bulges out of its
coarse triangles' chords (it is pushed out of the body between the coarse points), the one under it as much as
the one over it. Pushed once at the end instead, with no stretch passes after the pushes, the hems of the outer
garments over a flared skirt crumpled into spikes, and more stayed through (the 36 top-over-bottom outfits of
``tryon bench --only outfits``: 371 layer-penetrating vertices that way, 130 this way).
``layer_penetrating_vertices`` counts what is still more than ``LAYER_TOLERANCE`` on the body's side of a
garment under it, each triangle's outward side taken on the shown meshes as they end.

Tuck: a top and a bottom in one outfit are layered by ``tuck``: ``out`` (the default) puts the bottom under
every top (the top's hem falls over the waistband), ``in`` puts the bottom right over the innermost top (its
band holds that top's hem inside; a second top stays over both). Before the first step the tucked top's tail,
what lies under the bottom's top, is gathered to fit inside it (``tail_gathered``: round the body to the
bottom's girth, and above the crotch in trousers or shorts).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from tryon.body.types import Body
from tryon.garment.model import GarmentModel
from tryon.garment.split import split_pieces
from tryon.geometry import stack_meshes
from tryon.sim.blocks import at_once
from tryon.sim.collision.cloth import (
    build_tri_grid, face_sides, outward_from_axes, overlap, push_layer, signed_face_normals,
)
from tryon.sim.collision.crossings import layer_depths, signed_distances
from tryon.sim.collision.over_fixed import OverFixed
from tryon.sim.constraints import cap_stretch
from tryon.sim.finish import TryOnResult, full_mesh, result
from tryon.sim.landmarks import body_landmarks, hull_girth, torso_points
from tryon.sim.pieces import piece_kinds, piece_labels, waistband_mask
from tryon.sim.relax import collide_all, relax, relaxation_passes, relaxation_round
from tryon.sim.settings import SimSettings
from tryon.sim.start import start
from tryon.sim.state import Drape
from tryon.sim.step import step_drape
from tryon.sim.tuning import TUNING, Tuning

# At most this many garments in one outfit (an undershirt, a shirt, a layer over them; or a top and a bottom
# and a layer).
MAX_GARMENTS = 3
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
# m: how far outside a bottom's surface a top's point may hang and still be tucked under it (tuck ``in``): a
# loose shirt hangs a few centimetres off the hips.
TUCK_REACH = 0.06
# m: the inner triangles' grid cell (about the coarse edge length).
LAYER_CELL = 0.03
# Layer collisions after the relaxation, each followed by a relaxation round and the body collision of every
# garment: the relaxation moves each garment on its own (a waistband climbing to where it fits). The 36
# top-over-bottom outfits of ``tryon bench --only outfits``: layer-penetrating vertices 122 after 4 rounds, 15
# after 8; springs over their limits 3,633 and 2,927 (10,592 with the layers' push the last word, no springs).
FINAL_LAYER_ROUNDS = 8
# x natural length: after each of those rounds no spring is left longer (issue 5: never beyond 3 x). Pushed out
# of a layer and the body, a band far too small for its body was left far past it (the T-shirt M tucked into the
# skirt S on the medium body: 6.1 x, max_strain 5.1; 18 of the 39 outfits of ``tryon bench --only outfits`` had
# a spring over 3 x); past it the spring wins, and the metrics report the cloth left inside. Not the step's tear
# guard (2.5 x): pulled back that far, the bench's outfits crossed their layers more (201 -> 228 vertices; 193
# at 3 x).
FINAL_CAP = 3.0
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
TUCKS = ("out", "in")
# m: a top tucked into trousers or shorts ends at least this far above the body's crotch (``tail_gathered``):
# clear of the gap between the thighs, where the bottom's crotch seam lies.
TAIL_ABOVE_CROTCH = 0.03
# m: the height of the slabs in which a tucked tail's girth is gathered to the bottom's (``_gather_round``).
GATHER_SLAB = 0.02
# The share of the top's shown vertices at the band's height, over the bottom, that must be on the tuck's side of
# its surface for ``tuck_as_asked``.
TUCK_SHARE = 0.9

OutfitFrameCallback = Callable[[int, list], bool]


@dataclass
class OutfitResult:
    """results: one ``TryOnResult`` per garment, in layer order (innermost first); order: for each of those,
    its index in the models given to ``drape_outfit``; metrics: the outfit's (steps, wall_seconds,
    rest_reached, layer_penetrating_vertices, max_layer_penetration_mm, tuck, layers, tuck_as_asked)."""

    results: list[TryOnResult]
    order: list[int]
    metrics: dict = field(default_factory=dict)

    @property
    def vertices(self) -> np.ndarray:
        """(n, 3) m: every garment's shown mesh, in layer order, one after the other."""
        return stack_meshes([(r.vertices, r.faces) for r in self.results])[0]

    @property
    def faces(self) -> np.ndarray:
        """(f, 3) int64: every garment's triangles, indexing ``vertices``."""
        return stack_meshes([(r.vertices, r.faces) for r in self.results])[1]

    @property
    def strain(self) -> np.ndarray:
        """(n,) per vertex of ``vertices``: the largest strain of its springs."""
        return np.concatenate([r.strain for r in self.results])


def tuck_in(drapes: list[Drape], faces: list[np.ndarray], sides: list[np.ndarray]) -> None:
    """Put each top under the bottom layered over it before the first step (tuck ``in``): the top's points
    over the bottom's surface, within ``TUCK_REACH``, go ``LAYER_GAP`` under it, the bottom held still.
    Aligned each on its own, a shirt's hem hangs over the trousers' hips; pushed in only by the layer
    collision, step by step, it would be caught half in, half out."""
    category = [d.model.garment.meta.category for d in drapes]
    for j, d in enumerate(drapes):
        if category[j] != "bottom":
            continue
        for i in range(j):
            x = [drapes[i].state.x, d.state.x]
            collide_layers(x, [drapes[i].state.x_prev, d.state.x_prev],
                           [drapes[i].state.inv_mass, np.zeros(len(x[1]))], [faces[i], faces[j]], [sides[i], sides[j]],
                           LAYER_GAP, both_ways=True, reach=TUCK_REACH)


def tail_gathered(top: Drape, bottom: Drape, body: Body) -> GarmentModel | None:
    """The top's garment with its tail, the part under ``bottom``'s top, gathered to fit in it: round the body
    to the bottom's girth (``_gather_round``), and for trousers or shorts up to end ``TAIL_ABOVE_CROTCH`` above
    the body's crotch; None when nothing of it is under the bottom. Worn, that cloth is folded and bunched inside
    the band, finer than the coarse mesh's triangles show. Kept at its own girth, a shirt wider than the band
    pushed the band out past its limit; kept at its length, the cloth hanging below the crotch lay across the gap
    between the thighs, where the bottom's crotch seam goes, and the layer push held the seam centimetres below
    the crotch, stretching the seat and thighs (the T-shirt M in the trousers M on 170 / 92 / 76 / 98: shown
    2.35x, tight). The gathered shape's lengths become the springs' natural ones (``GarmentModel.resized``; the
    alignment only translates a top, so the aligned move is the rest shape's move)."""
    garment, x = top.model.garment, top.state.x
    above = float(bottom.state.x[:, 1].max())
    limbs = [o for _, _, o in top.model.openings]
    hems = [loop for loop in garment.coarse_loops if not any(np.array_equal(loop, o) for o in limbs)]
    if not hems:
        return None
    hem = min(hems, key=lambda loop: float(x[loop, 1].mean()))
    tail = _reached_below(hem, garment.springs, x[:, 1] < above)
    if not tail.any():
        return None
    moved = x.copy()
    target = body_landmarks(body).crotch_y + TAIL_ABOVE_CROTCH
    lowest = float(x[tail, 1].min())
    if any(limb == "leg" for _, limb, _ in bottom.model.openings) and lowest < target < above:
        moved[tail, 1] = above - (above - x[tail, 1]) * (above - target) / (above - lowest)
    _gather_round(moved, tail, bottom.state.x, torso_points(body))
    return garment.resized(garment.coarse_vertices + (moved - x))


def _gather_round(moved: np.ndarray, tail: np.ndarray, bottom: np.ndarray, torso: np.ndarray) -> None:
    """Gather the ``tail`` points (k,) bool of ``moved`` (k, 3) m, in place, round the body to fit inside
    ``bottom`` (b, 3) m: in each ``GATHER_SLAB`` of height their girth is scaled about the bottom's centre there
    to the bottom's girth less two ``LAYER_GAP`` round it (the excess folded finer than the coarse mesh shows, as
    a shirt's round a belt), but not below the body's (``torso`` (t, 3) m, its vertices) and a ``LAYER_GAP``
    round it: a bottom too small for the body is stretched over the shirt, not the shirt into the body."""
    for y in np.arange(moved[tail, 1].min(), moved[tail, 1].max() + GATHER_SLAB, GATHER_SLAB):
        here = tail & (np.abs(moved[:, 1] - y) <= GATHER_SLAB / 2)
        around = np.abs(bottom[:, 1] - y) <= GATHER_SLAB
        if here.sum() < 3 or around.sum() < 3:
            continue
        room = hull_girth(bottom[around]) - 4.0 * np.pi * LAYER_GAP
        body = np.abs(torso[:, 1] - y) <= GATHER_SLAB / 2
        if body.sum() >= 3:
            room = max(room, hull_girth(torso[body]) + 2.0 * np.pi * LAYER_GAP)
        girth = hull_girth(moved[here])
        if girth <= room or room <= 0.0:
            continue
        centre = bottom[around][:, [0, 2]].mean(axis=0)
        moved[np.ix_(here, [0, 2])] = centre + (moved[np.ix_(here, [0, 2])] - centre) * (room / girth)


def _reached_below(start: np.ndarray, springs: np.ndarray, below: np.ndarray) -> np.ndarray:
    """(k,) bool: the points ``below`` (k,) bool reached from ``start`` (point ids) along ``springs`` (s, 2)
    through points ``below`` only (a top's tail from its hem, not its sleeves)."""
    a, b = springs[:, 0], springs[:, 1]
    keep = below[a] & below[b]
    n = len(below)
    graph = coo_matrix((np.ones(int(keep.sum())), (a[keep], b[keep])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    return below & np.isin(label, label[start[below[start]]])


def gather(d: Drape, pressed: np.ndarray) -> None:
    """Cloth pressed between an outer layer and what is under it (``pressed`` (k,) bool, on a contact plane) may
    shorten: the springs with both ends so squeezed lose their compression correction (``d.state.table``'s third
    column; the others get back their packed one, ``d.model.table``'s, unless still folded, ``DrapeState.folded``).
    A loose shirt tucked into a waistband gathers into folds finer than the coarse mesh's 2-3 cm triangles can
    show; kept at their natural lengths its springs would stretch the band over it instead."""
    squeezed = pressed & d.state.has_plane
    both = squeezed[d.model.springs[:, 0]] & squeezed[d.model.springs[:, 1]]
    both[d.state.folded] = True
    d.state.table[:, 2] = np.where(both, 0.0, d.model.table[:, 2])


def layer_order(categories: list[str], tuck: str = "out") -> list[int]:
    """The garments' layer order, innermost first, as indices into ``categories`` (top | bottom | dress, in
    the order given, innermost first): the tops and dresses keep their order; a bottom goes under them all
    (tuck ``out``) or right over the first (``in``). ValueError for two bottoms or an unknown tuck."""
    if tuck not in TUCKS:
        raise ValueError(f"tuck must be one of {', '.join(TUCKS)}, not {tuck!r}")
    bottoms = [i for i, c in enumerate(categories) if c == "bottom"]
    if len(bottoms) > 1:
        raise ValueError("an outfit has at most one bottom (skirt, trousers or shorts)")
    tops = [i for i, c in enumerate(categories) if c != "bottom"]
    if not bottoms:
        return tops
    if tuck == "out" or not tops:
        return bottoms + tops
    return tops[:1] + bottoms + tops[1:]


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


def each_garment(fn: Callable, drapes: list[Drape]) -> list:
    """``[fn(d) for d in drapes]``, the garments at once where the caller may use two threads
    (``blocks.at_once``); ``fn`` touches only its own drape (a step, a relaxation, a shown mesh)."""
    return at_once(fn, drapes)


def drape_outfit(body: Body, models: list[GarmentModel], settings: SimSettings = SimSettings(),
                 tuck: str = "out", tuning: Tuning = TUNING,
                 on_frame: OutfitFrameCallback | None = None) -> OutfitResult:
    """Drape ``models`` (1 to ``MAX_GARMENTS``, innermost first; see ``layer_order`` for ``tuck``) together on
    ``body``; see the module doc. ``on_frame(step, [coarse positions (k_i, 3) per garment in layer order])``
    after each step; False stops the loop."""
    t_start = time.perf_counter()
    if not 1 <= len(models) <= MAX_GARMENTS:
        raise ValueError(f"an outfit has 1 to {MAX_GARMENTS} garments, not {len(models)}")
    order = layer_order([m.meta.category for m in models], tuck)
    # an outfit's simulated meshes are not untangled (``collision/untangle.py``): a point moved out of its own
    # garment's fold goes through the garment under it as readily, where the layers' sides are the layer
    # collision's (a long-sleeve M over an A-line skirt on the small body, untangled in its steps, pushed the skirt
    # into folds of 1,500 crossings and never came to rest). Their shown meshes are, each round of it followed by
    # the push off the shown meshes under it (``full_mesh.follow_coarse``'s ``also_collide``): untangled without
    # that push, a long-sleeve S over a T-shirt M ended with a shown vertex 5 mm into the torso at an armpit
    drapes = [start(body, models[i], settings, replace(tuning, untangle_every=0)) for i in order]
    faces = [np.ascontiguousarray(d.model.garment.coarse_faces, dtype=np.int64) for d in drapes]

    def sides():
        """Which side of each triangle is outside, where the garments are now."""
        return [face_sides(d.state.x, f, outward_from_body(d.state.x, body)) for d, f in zip(drapes, faces)]
    if tuck == "in":
        for k in range(len(drapes) - 1):  # a top with the bottom right over it: its tail gathered in
            if drapes[k + 1].model.garment.meta.category == "bottom":
                gathered = tail_gathered(drapes[k], drapes[k + 1], body)
                if gathered is not None:
                    drapes[k] = start(body, gathered, settings, replace(tuning, untangle_every=0))
        tuck_in(drapes, faces, sides())
    layered_from = max(d.control.startup for d in drapes)  # every body complete: the layers may collide
    asleep = np.zeros(len(drapes), dtype=np.bool_)
    stopped, n = False, 0
    for n in range(1, settings.max_steps + 1):
        each_garment(step_drape, [d for d, sleeping in zip(drapes, asleep) if not sleeping])
        if n > layered_from and len(drapes) > 1:
            before = [d.state.x.copy() for d in drapes]
            pressed = [np.zeros(len(d.state.x), dtype=np.bool_) for d in drapes]
            for d in drapes:
                d.state.layer_has[:] = False
            collide_layers([d.state.x for d in drapes], [d.state.x_prev for d in drapes],
                           [d.state.inv_mass for d in drapes], faces, sides(), LAYER_GAP, 0.0,
                           [d.state.layer_planes for d in drapes], LAYER_MAX_PUSH, pressed,
                           both_ways=True, on_body=[d.state.has_plane for d in drapes])
            for k, d in enumerate(drapes):
                gather(d, pressed[k])
                # pushed: awake (the push's move counts in its next step's rest test)
                if asleep[k] and np.abs(d.state.x - before[k]).max() > tuning.rest_move:
                    asleep[k] = False
        for k, d in enumerate(drapes):
            if n > layered_from and d.state.rest_run >= settings.steps_of(settings.rest_steps):
                asleep[k] = True
        # the start-up is not shown (``run.settle``)
        if on_frame is not None and n > layered_from and on_frame(n, [d.state.x for d in drapes]) is False:
            stopped = True
            break
        if asleep.all():
            break
    for d in drapes:  # each relaxes on its own body, not on the loop's last layer planes
        d.state.layer_has[:] = False
    relaxations = each_garment(relax, drapes)
    if len(drapes) > 1:
        passes = [relaxation_passes(d) for d in drapes]
        for _ in range(FINAL_LAYER_ROUNDS):
            for d in drapes:
                d.state.layer_has[:] = False
                d.state.x_prev[:] = d.state.x
            collide_layers([d.state.x for d in drapes], [d.state.x_prev for d in drapes],
                           [d.state.inv_mass for d in drapes], faces, sides(), LAYER_GAP, both_ways=True,
                           planes=[d.state.layer_planes for d in drapes],
                           on_body=[d.state.has_plane for d in drapes])
            for d, (springs, run) in zip(drapes, passes):
                relaxation_round(d, springs, run)
                collide_all(d)
                cap_stretch(d.state.x, d.state.inv_mass, d.model.springs, d.model.rest, FINAL_CAP,
                            d.model.tuning.tear_passes)
    full_faces = [np.ascontiguousarray(d.model.garment.faces, dtype=np.int64) for d in drapes]
    shown = [full_mesh(drapes[0], alone=False)]
    for j in range(1, len(drapes)):
        # each outer shown mesh built off the shown meshes under it, those held still
        shown.append(full_mesh(drapes[j], off_shown([s[0] for s in shown], full_faces[: j + 1], body), alone=False))
    full = [s[0] for s in shown]
    full_sides = [face_sides(v, f, outward_from_body(v, body)) for v, f in zip(full, full_faces)]
    results = [result(d, r, f, s[1], stopped) for d, r, f, s in zip(drapes, relaxations, full, shown)]
    count, deepest = layer_metrics(full, full_faces, full_sides)
    tops = [k for k, d in enumerate(drapes) if d.model.garment.meta.category != "bottom"]
    bottoms = [k for k, d in enumerate(drapes) if d.model.garment.meta.category == "bottom"]
    tucked = None
    if tops and bottoms:
        bottom = drapes[bottoms[0]]
        garment = bottom.model.garment
        band = waistband_mask(bottom.state.x, garment.coarse_faces, "bottom", garment.coarse_loops, bottom.model.piece)
        b = bottoms[0]
        heights = bottom.state.x[band, 1]
        tucked = tuck_as_asked(full[tops[0]], full[b], full_faces[b], full_sides[b],
                               (float(heights.min()), float(heights.max())) if band.any() else None, tuck)
    metrics = {
        "steps": int(n),
        "sim_seconds": float(n * float(settings.time_step)),
        "wall_seconds": float(time.perf_counter() - t_start),
        "rest_reached": bool(asleep.all()) and not stopped,
        "stopped": bool(stopped),
        "tuck": tuck,
        "layers": [d.model.garment.meta.id for d in drapes],
        "layer_penetrating_vertices": int(count),
        "max_layer_penetration_mm": round(1000.0 * float(deepest), 3),
        "tuck_as_asked": tucked,
    }
    return OutfitResult(results=results, order=order, metrics=metrics)


def tuck_as_asked(top: np.ndarray, bottom: np.ndarray, bottom_faces: np.ndarray, bottom_sides: np.ndarray,
                  band: tuple[float, float] | None, tuck: str) -> bool | None:
    """Whether the innermost top's shown vertices ``top`` (k, 3) m at the height of the bottom's waistband
    (``band``: its lowest and highest y, m) lie outside the bottom's shown surface (tuck ``out``) or inside it
    (``in``): at least ``TUCK_SHARE`` of those over the bottom's surface within ``LAYER_REACH``, judged by the
    signed distance along the normal of the triangle each lies over (the bottom's points ``bottom`` (m, 3) m,
    triangles ``bottom_faces`` turned outward by ``bottom_sides``, ``face_sides``). What a person sees: the
    hem over the band or under it. None without a band, or when no top vertex is there (a top that ends
    above the waist)."""
    if band is None:
        return None
    level = top[(top[:, 1] >= band[0]) & (top[:, 1] <= band[1])]
    if not len(level):
        return None
    s = signed_distances(level, bottom, bottom_faces, signed_face_normals(bottom, bottom_faces, bottom_sides),
                         LAYER_REACH)
    s = s[np.isfinite(s)]
    if not len(s):
        return None
    share = float(np.mean(s > 0.0 if tuck == "out" else s < 0.0))
    return share >= TUCK_SHARE


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


def piece_categories(model: GarmentModel) -> list[str] | None:
    """For a garment file of separate garments with a bottom among them (a MakeHuman outfit: a shirt and
    trousers), each piece's category (``pieces.piece_kinds``: ``bottom`` for the pieces hanging from a waist,
    ``top`` or ``dress`` beside it by how far down it reaches); None for a garment of one piece, or of pieces
    that are not a top and a bottom."""
    return piece_kinds(model.coarse_vertices, model.coarse_faces, model.meta.category,
                       piece_labels(model.coarse_faces, len(model.mass)))


def drape_pieces(body: Body, model: GarmentModel, categories: list[str], settings: SimSettings = SimSettings(),
                 on_frame: Callable[[int, np.ndarray], bool] | None = None, tuning: Tuning = TUNING) -> TryOnResult:
    """Drape a file of separate garments (``piece_categories``) as an outfit, its top over its bottom (tuck
    out), and answer as for one garment: the shown mesh, strain and coarse positions in the file's own order,
    the metrics of the whole (counts summed, worst values kept) with the outfit's layer figures beside them.
    ``on_frame(step, coarse (k, 3) in the file's order)`` as for ``drape``."""
    models, where = split_pieces(model, categories)
    k = len(model.coarse_index)

    def whole(coarse: list[np.ndarray], order: list[int]) -> np.ndarray:
        x = np.empty((k, 3))
        for layer, i in enumerate(order):
            x[where[i].coarse] = coarse[layer]
        return x

    order = layer_order(categories, "out")

    def frames(step: int, coarse: list[np.ndarray]) -> bool:
        return on_frame(step, whole(coarse, order))

    out = drape_outfit(body, models, settings, "out", tuning, None if on_frame is None else frames)
    vertices = np.empty((len(model.vertices), 3))
    strain = np.empty(len(model.vertices))
    for layer, i in enumerate(out.order):
        vertices[where[i].full] = out.results[layer].vertices
        strain[where[i].full] = out.results[layer].strain
    metrics = merged_metrics([r.metrics for r in out.results])
    metrics.update({key: out.metrics[key] for key in ("steps", "sim_seconds", "wall_seconds", "rest_reached",
                                                      "stopped", "layer_penetrating_vertices",
                                                      "max_layer_penetration_mm")})
    metrics["layered_pieces"] = len(models)
    return TryOnResult(vertices=vertices, faces=model.faces, strain=strain,
                       coarse=whole([r.coarse for r in out.results], out.order), metrics=metrics)


def merged_metrics(parts: list[dict]) -> dict:
    """One garment's metrics from its pieces' (``finish.result``'s keys): counts summed, the worst of maxima
    kept, lists joined, flags all-true (``stays_up``, ``relaxed``, ``openings_on_limbs`` where any piece has
    openings) or any-true (``sized_to_body``, ``grown``)."""
    first = parts[0]
    out = dict(first)
    for key in ("penetrating_vertices", "body_through_vertices", "last_step_contacts"):
        out[key] = sum(int(p[key]) for p in parts)
    for key in ("max_penetration_mm", "max_body_through_mm", "max_strain", "display_max_strain", "slid_cm",
                "kinetic_energy_per_kg", "polish_rounds"):
        out[key] = max(p[key] for p in parts)
    out["strain_by_kind"] = {
        kind: {"max": max(p["strain_by_kind"][kind]["max"] for p in parts), "limit": v["limit"],
               **{count: sum(p["strain_by_kind"][kind].get(count, 0) for p in parts)
                  for count in ("over", "over_on_body") if count in v}}
        for kind, v in first["strain_by_kind"].items()}
    tight: dict[str, int] = {}
    for p in parts:
        for place, n in p["too_tight"].items():
            tight[place] = tight.get(place, 0) + n
    out["too_tight"] = dict(sorted(tight.items(), key=lambda kv: -kv[1]))
    out["limb_openings"] = [o for p in parts for o in p["limb_openings"]]
    out["openings_on_limbs"] = all(o["ok"] for o in out["limb_openings"]) if out["limb_openings"] else None
    out["stays_up"] = all(p["stays_up"] for p in parts)
    out["relaxed"] = all(p["relaxed"] for p in parts)
    out["sized_to_body"] = any(p["sized_to_body"] for p in parts)
    out["grown"] = any(p["grown"] for p in parts)
    out["parts_tested"] = sorted({name for p in parts for name in p["parts_tested"]})
    out["relax_move_mm"] = [max(p["relax_move_mm"][0] for p in parts), max(p["relax_move_mm"][1] for p in parts)]
    return out
