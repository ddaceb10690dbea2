"""The displayed (full) mesh of a drape: it follows the simulated coarse mesh (the paper's re-attachment,
``GarmentModel.expand``), its stretch is held to the cloth's limits, and it is pushed out of the offset
body, so what the page shows neither stretches beyond the cloth nor penetrates.

Why the stretch passes: the coarse triangles are free to shear and buckle between their springs (a
triangle whose edges are all within their limits, one of them compressed, can stretch 40-80 % across), and
the full triangles attached to them stretch with them. On the medium body 24-32 % of the full edges of the
catalogue T-shirt and A-line skirt M and the DiffAvatar T-shirt were over 10 %, a few up to 50-60 %
(p99 0.23-0.27), while no coarse spring was over its limit. Three rounds of ten stretch passes over the
full mesh's own springs, each followed by the collision, bring that to p99 0.12-0.14, max 0.19-0.26,
moving the vertices 4-6 mm (p99) from where the re-attachment put them, for ~11 ms per drape on the
7,342-vertex perf T-shirt (``python3 -m tryon.bench.perf``'s garment). Where a coarse triangle cuts across a
thin part (a hand, a foot), the full mesh pushed out round it still stretches there: collision wins.

Why the lift: every full vertex outside the offset body is not enough; a triangle between them can still cut
under the skin (the catalogue tops' long thin shoulder-seam triangles chord across the shoulders, and the
shoulders showed through them by up to 9 mm). After the collision of every round but the last, the triangles
the skin pokes through are lifted to the offset surface (``show_through.lift_over_skin``), and the next round's
stretch passes carry the lift to their neighbours. The 90 drapes of the fit bench (``tryon bench --only fit``):
2,739 body vertices through the shown meshes without the lift, 129 with it (the deep ones are hands inside
long sleeves, below), the median of the shown meshes' largest strain 0.19 and 0.185. Lifted in the last round
too, 51 showed through, but the lift stayed in the shown mesh as stretch (median 0.23): the page reports that
strain.

Why the settling rounds (a garment worn alone): the last collisions push points out with their neighbours left
where they were (a crotch vertex pushed into the crease between the thighs stretched its edges to 0.32 on the
large body's trousers XL). Stretch passes with the pushed points held still take that back through the points
the body does not hold, then the collision and the lift again (``_settle_free``).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from tryon.garment.model import GarmentModel
from tryon.sim.collision.collider import BodyCollider
from tryon.sim.collision.collider import relevant_parts
from tryon.sim.collision.untangle import untangle_mesh
from tryon.sim.constraints import pack_springs, satisfy_springs, spring_strain
from tryon.sim.show_through import lift_over_skin

# Rounds of (DISPLAY_PASSES stretch passes over the full mesh's springs, then the collision).
DISPLAY_ROUNDS = 3
DISPLAY_PASSES = 10
# Most collision calls after the rounds (each repeats its part loop ROUNDS times): a point pushed out of one
# part into another (crotch, armpit) is caught by the next call.
FULL_COLLIDE_CALLS = 4
# m, collide_points' hold_depth for those calls: 0 = a point pinched between two parts (pushed out of each into
# the other in every round) ends where its pushes leave it least deep, between the two (a sleeve between a
# forearm and the belly it rests on), not on one part's offset surface as deep in the other as the offset.
PINCHED_LEAST_DEEP = 0.0
# m: the deepest skin a triangle is lifted over. Deeper is not a chord across a curve (a 5 cm triangle over a
# shoulder of 4 cm radius sags 8 mm) but a thin part poking through (a hand through a long sleeve's cuff that
# covers it), which a lift along the skin's normals tore into spikes (a shown-mesh strain of 3.1).
SKIN_DEEPEST = 0.01
# Rounds of (stretch passes of the points the body does not hold, collision, lift) at the end: the collision
# calls and the lifts stretch the shown edges between a pushed point and its neighbours; with the body's points
# held, the neighbours take it back. The fit bench's 90 drapes with no spring over but a shown edge over 16 %: 7
# without them, 4 with three rounds (body vertices through the shown meshes 18 -> 1), 2 with the lifted points
# held too and the passes once more after the last round (one of them, the dress M, reported tight).
SETTLE_ROUNDS = 3


def follow_coarse(model: GarmentModel, coarse: np.ndarray, collider: BodyCollider, limits: np.ndarray,
                  contact_offset: float, floor_y: float = 0.0,
                  also_collide: Callable[..., int] | None = None,
                  untangle_step: float = 0.0, untangle_rounds: int = 1, settle: bool = True
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The full mesh (n, 3) m on the draped coarse positions ``coarse`` (k, 3), see the module doc, and the
    body parts (int64 indices) it was collided with. ``limits`` (3,): strain limits by spring kind (the
    full mesh's springs are structural and shear); ``contact_offset`` m: lambda of eq. 4; nothing goes
    below ``floor_y`` m. ``also_collide(full, full_prev, moved=None)``: another collider (an outfit's shown
    garments under this one; ``moved`` (n,) bool: only these points moved since its last call), called after the
    body collision of every round, so that the stretch passes spread its pushes to
    the neighbours as they spread the body's, and once more before the last body collisions (the body has the
    last word: pushed off an inner layer folded at an armpit, a long-sleeve's shown vertex went 3 mm into the
    torso). ``untangle_step`` m, ``untangle_rounds``: before the stretch passes of every round but the last,
    rounds of contour minimisation (at most ``untangle_rounds``, until one finds no crossing), each moving a
    point at most ``untangle_step`` and followed by ``also_collide``. ``settle``: end with the settling rounds
    (``_settle_free``); an outfit's garments do not, as the rounds hold still only the points the body pushed,
    and the layers under a garment hold it too (with them, the outfits bench's layer-penetrating vertices rose
    from 11 to 21, with the points the layers pushed held as well to 18)."""
    full = np.ascontiguousarray(model.expand(coarse))
    np.maximum(full[:, 1], floor_y, out=full[:, 1])
    full_prev = full.copy()
    contact = np.zeros(len(full), dtype=np.bool_)
    ones = np.ones(len(full))
    active = np.ones(len(full), dtype=np.bool_)
    parts = relevant_parts(collider.body.maps, full.min(axis=0), full.max(axis=0), 0.01)
    pairs, rest, kind = model.display_springs
    ends, table = pack_springs(pairs, rest, kind, limits, np.zeros(3))
    table[:, 1] = 0.0  # stretch only: the full mesh may buckle as the coarse one does (l0 = 0: not visited)
    for r in range(DISPLAY_ROUNDS):
        if untangle_step and r < DISPLAY_ROUNDS - 1:
            faces, edges, adjacent = model.edge_faces
            # the shown mesh's own crossings where its triangles, following the coarse ones, cut into each other
            # in a fold; the stretch passes and the collision after it have the last word. An outer garment is
            # pushed off the ones under it after each round: a point moved out of its own fold goes through the
            # layer under it as readily
            untangle_mesh(full, full_prev, ones, faces, edges, adjacent, untangle_step, untangle_rounds,
                          after=also_collide)
        satisfy_springs(full, ones, ends, table, DISPLAY_PASSES)
        active[:] = True
        collider.collide(full, full_prev, ones, active, parts, contact_offset, 0.0, 0.0, contact)
        if r < DISPLAY_ROUNDS - 1:
            # over the offset surface, where the vertices rest: the next round's stretch passes pull it back part way
            lift_over_skin(collider, parts, full, model.faces, collider.margin, SKIN_DEEPEST)
        if also_collide is not None:
            also_collide(full, full_prev)
    if also_collide is not None:
        # right after the last round's push, not twice the same: a call stops at its round cap with points still
        # through the layer under it (without this one the outfits bench's layer-penetrating vertices 18 -> 55)
        also_collide(full, full_prev)
        active[:] = True  # pushed off the layers under it, anywhere
    elif DISPLAY_ROUNDS:
        active[:] = contact  # the last round's collision tested every point: only those it pushed can be inside
    for _ in range(FULL_COLLIDE_CALLS):
        # the later calls test only the points the last one moved (the others were outside every part)
        if not collider.collide(full, full_prev, ones, active, parts, contact_offset, 0.0, 0.0, contact,
                                hold_depth=PINCHED_LEAST_DEEP):
            break
        active[:] = contact
    if settle:
        _settle_free(full, full_prev, contact, ends, table, collider, parts, contact_offset, model.faces)
    return full, parts


def _settle_free(full: np.ndarray, full_prev: np.ndarray, contact: np.ndarray, ends: np.ndarray, table: np.ndarray,
                 collider: BodyCollider, parts: np.ndarray, contact_offset: float, faces: np.ndarray) -> None:
    """After the collision calls, ``SETTLE_ROUNDS`` rounds of: the stretch passes with the points the last
    collision pushed (``contact`` (n,) bool) and the last lift moved held still, so the stretch the pushes and the
    lift left is taken back by the points the body does not hold, none is pulled into it and the lift is not
    undone; every point's collision (a pinched one where its pushes leave it least deep); the lift of the
    triangles the skin pokes through. Then those stretch passes once more (the last round's collision and lift
    stretch the edges from the points they moved to their neighbours: the large body's long-sleeve L 0.15 -> 0.21
    over a shoulder) and the body's collision: it has the last word. In place on ``full`` (n, 3) m; ``ends`` /
    ``table`` the full mesh's packed springs (stretch only)."""
    ones = np.ones(len(full))
    active = np.ones(len(full), dtype=np.bool_)
    held = contact.copy()
    for r in range(SETTLE_ROUNDS + 1):  # the rounds, then their passes and collision once more
        satisfy_springs(full, np.where(held, 0.0, 1.0), ends, table, DISPLAY_PASSES)
        active[:] = True
        collider.collide(full, full_prev, ones, active, parts, contact_offset, 0.0, 0.0, contact,
                         hold_depth=PINCHED_LEAST_DEEP)
        if r == SETTLE_ROUNDS:
            break
        before = full.copy()
        lift_over_skin(collider, parts, full, faces, collider.margin, SKIN_DEEPEST)
        held = contact | np.any(full != before, axis=1)


def display_strain(full: np.ndarray, model: GarmentModel) -> float:
    """Largest strain (length / natural length - 1) of the full mesh's structural and shear springs at the
    positions ``full`` (n, 3): how far the displayed mesh stretches anywhere."""
    pairs, rest, _ = model.display_springs
    return float(spring_strain(full, pairs, rest).max()) if len(rest) else 0.0
