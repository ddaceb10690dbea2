"""Tuck: a top and a bottom in one outfit layered top over bottom (``out``) or bottom over top (``in``).

``layer_order``: ``out`` (the default) puts the bottom under every top (the top's hem falls over the waistband),
``in`` puts the bottom right over the innermost top (its band holds that top's hem inside; a second top stays over
both). Before the first step the tucked top's tail, what lies under the bottom's top, is gathered to fit inside it
(``tail_gathered``: round the body to the bottom's girth, and above the crotch in trousers or shorts) and put under
the bottom (``tuck_in``); in the steps, its cloth pressed under the band may shorten (``gather``). At the end
``tuck_as_asked`` says whether what a person sees is the tuck asked for.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from tryon.body.types import Body
from tryon.garment.model import GarmentModel
from tryon.sim.collision.cloth import signed_face_normals
from tryon.sim.collision.crossings import signed_distances
from tryon.sim.landmarks import body_landmarks, hull_girth, torso_points
from tryon.sim.layers import LAYER_GAP, LAYER_REACH, collide_layers
from tryon.sim.state import Drape

TUCKS = ("out", "in")
# m: how far outside a bottom's surface a top's point may hang and still be tucked under it (tuck ``in``): a
# loose shirt hangs a few centimetres off the hips.
TUCK_REACH = 0.06
# m: a top tucked into trousers or shorts ends at least this far above the body's crotch (``tail_gathered``):
# clear of the gap between the thighs, where the bottom's crotch seam lies.
TAIL_ABOVE_CROTCH = 0.03
# m: the height of the slabs in which a tucked tail's girth is gathered to the bottom's (``_gather_round``).
GATHER_SLAB = 0.02
# The share of the top's shown vertices at the band's height, over the bottom, that must be on the tuck's side of
# its surface for ``tuck_as_asked``.
TUCK_SHARE = 0.9


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
