"""An outfit: up to three garments draped at once, each over the ones under it (issue 29).

Method. Every garment is its own drape (``start``, ``step``, ``relax``: its springs, its contacts with the body,
its own start-up), stepped in lockstep; after each step the layers collide (``layers.collide_layers``: each
garment kept ``LAYER_GAP`` outside the ones under it), once every garment's start-up is over (each drape grows
the body and turns the arms on its own schedule), on the body all garments share. A top and a bottom are layered
as ``tuck`` asks (``tuck.layer_order``; a top tucked in has its tail gathered inside the bottom first).

Both cores: the garments' steps (and their relaxations) touch only their own drape, and the kernels release the
GIL, so where the calling thread may use two threads (``numba.get_num_threads``: the service's pool gives a
try-on running alone both cores) they run at once, one garment a thread (``blocks.at_once``), the same numbers as
one after the other. A garment at rest that no layer pushed is not stepped (it sleeps until a push moves it by
more than ``tuning.rest_move``).

The end: each garment relaxes on its own, then ``FINAL_LAYER_ROUNDS`` rounds of the layers' collision, each
followed by one relaxation round of every garment (``relax.relaxation_round``: its over-long springs back to their
limits, a point the layers pushed held on the layer under it by that layer's plane as in the steps) and the body
collision (nothing through the body either). Pushed off the layer under it with no springs after the push, an
outer garment was left with springs far over their limits where it lay over the inner one's folds (a T-shirt S
over trousers M, both advised for 170 / 92 / 76 / 98: a back spring at 43 %, "too tight at the hips"). Then the
shown meshes are built innermost first, each off the ones under it (``layers.off_shown``), and the layers'
figures taken on them (``layers.layer_metrics``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from tryon.body.types import Body
from tryon.garment.model import GarmentModel
from tryon.garment.split import split_pieces
from tryon.geometry import stack_meshes
from tryon.sim.blocks import at_once
from tryon.sim.collision.cloth import face_sides
from tryon.sim.constraints import cap_stretch
from tryon.sim.finish import TryOnResult, full_mesh, result
from tryon.sim.layers import LAYER_GAP, LAYER_MAX_PUSH, collide_layers, layer_metrics, off_shown, outward_from_body
from tryon.sim.pieces import piece_kinds, piece_labels, waistband_mask
from tryon.sim.relax import collide_all, relax, relaxation_passes, relaxation_round
from tryon.sim.settings import SimSettings
from tryon.sim.start import start
from tryon.sim.step import step_drape
from tryon.sim.tuck import gather, layer_order, tail_gathered, tuck_as_asked, tuck_in
from tryon.sim.tuning import TUNING, Tuning

# At most this many garments in one outfit (an undershirt, a shirt, a layer over them; or a top and a bottom
# and a layer).
MAX_GARMENTS = 3
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
        stepping = np.flatnonzero(~asleep)
        at_once(step_drape, [drapes[k] for k in stepping])
        if n > layered_from:  # a garment at rest (``step._at_rest``) is not stepped again; the layers still push it
            asleep[stepping] = [drapes[k].state.rest_reached for k in stepping]
        if n > layered_from and len(drapes) > 1:
            pressed = [np.zeros(len(d.state.x), dtype=np.bool_) for d in drapes]
            for d in drapes:
                d.state.layer_has[:] = False
            collide_layers([d.state.x for d in drapes], [d.state.x_prev for d in drapes],
                           [d.state.inv_mass for d in drapes], faces, sides(), LAYER_GAP, 0.0,
                           [d.state.layer_planes for d in drapes], LAYER_MAX_PUSH, pressed,
                           both_ways=True, on_body=[d.state.has_plane for d in drapes])
            for k, d in enumerate(drapes):
                gather(d, pressed[k])
        # the start-up is not shown (``run.settle``)
        if on_frame is not None and n > layered_from and on_frame(n, [d.state.x for d in drapes]) is False:
            stopped = True
            break
        if asleep.all():
            break
    for d in drapes:  # each relaxes on its own body, not on the loop's last layer planes
        d.state.layer_has[:] = False
    relaxations = at_once(relax, drapes)
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
    kept, lists joined, flags all-true (``stays_up``, ``relaxed``, ``balanced``, ``openings_on_limbs`` where any
    piece has openings) or any-true (``sized_to_body``, ``grown``)."""
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
    out["balanced"] = all(p["balanced"] for p in parts)
    for key in ("rest_speed_mm_s", "unbalanced_force"):
        figures = [p[key] for p in parts]
        out[key] = None if None in figures else max(figures)
    out["relaxed"] = all(p["relaxed"] for p in parts)
    out["sized_to_body"] = any(p["sized_to_body"] for p in parts)
    out["grown"] = any(p["grown"] for p in parts)
    out["parts_tested"] = sorted({name for p in parts for name in p["parts_tested"]})
    out["relax_move_mm"] = [max(p["relax_move_mm"][0] for p in parts), max(p["relax_move_mm"][1] for p in parts)]
    return out
