"""The start of a drape: the garment put on the body, its springs packed, a tangled start untangled.

``start`` aligns the garment (or takes given positions), sizes it when its units were guessed, packs its
springs (a bottom's waistband at the band limit), builds the body collider and the arms' turn back from the
sleeves' pose, picks the body parts the garment can reach, and decides how a garment that starts inside the
body gets out: the body grows from ``settings.grow_from`` of its radius (gravity off meanwhile; not the parts
that reach far from their axis, ``growing_parts``), or, with growth off, the points are pushed out and pinned
for ``tuning.pin_steps`` steps. See ``run.py``'s doc.
"""

from __future__ import annotations

import time

import numpy as np

from tryon.body.types import Body
from tryon.garment.model import GarmentModel
from tryon.sim.align import align_sized
from tryon.sim.arm_plan import ArmPlan, plan_arms
from tryon.sim.arms import ArmSchedule
from tryon.sim.collision.collider import BodyCollider, relevant_parts
from tryon.sim.constraints import folded_at
from tryon.sim.limbs import limb_openings
from tryon.sim.packed import packed_springs
from tryon.sim.pieces import piece_tops
from tryon.sim.settings import REFERENCE_STEP, SimSettings
from tryon.sim.state import BodyControl, Drape, DrapeModel, DrapeState
from tryon.sim.tuning import TUNING, Tuning


def start(body: Body, model: GarmentModel, settings: SimSettings = SimSettings(), tuning: Tuning = TUNING,
          initial: np.ndarray | None = None, motion=None, sized: bool = False,
          folded: np.ndarray | None = None) -> Drape:
    """A drape of ``model`` on ``body``, ready for its first step. ``initial`` (k, 3) m replaces the
    alignment (tests and stress scenes start from given positions; a re-posed drape from where its garment
    was). ``motion(collider)``: the body's start-up motion in place of the arms' turn back from the sleeves
    (``repose.PoseTransition``: the body moving from its old pose to this one, carrying the garment).
    ``sized``: ``model`` is a garment of guessed units already sized to this person (a re-pose of such a
    drape); an aligned one is sized here when its units were guessed. ``folded`` (q,) int64: the springs that
    start folded (``DrapeState.folded``: a re-pose carries its drape's); None: those the alignment shortened,
    none from ``initial``."""
    started = time.perf_counter()
    packed = packed_springs(model, settings)
    if initial is None:
        x, shape = align_sized(body, model, piece=packed.piece)
        if shape is not None:  # sized to this body (guessed units): its springs' natural lengths change too
            model = model.resized(shape)
            packed = packed_springs(model, settings)
            sized = True
        # the arms start as thin as the body starts growing: a cuff must have room for them then
        plan = plan_arms(body, x, model.meta.category, model.coarse_faces, model.coarse_loops, packed.piece,
                         start_scale=settings.grow_from if settings.grow_steps else 1.0)
    else:
        x = np.array(initial, dtype=np.float64)
        plan = ArmPlan(0.0, 0.0)
    piece, springs, rest, table, mass = packed.piece, packed.springs, packed.rest, packed.table, packed.mass
    inv_mass = np.where(mass > 0, 1.0 / np.where(mass > 0, mass, 1.0), 0.0)
    own = table.copy()  # the drape's own (``DrapeState.table``); the packed one is shared and never written
    if motion is not None:
        own[:, 3] = tuning.unfold_per_pass
    # cloth the alignment shortened (trouser legs made for a taller body, shortened to start above the feet:
    # ``legs.clear_feet``) lies folded finer than the coarse mesh shows: it pushes nothing until gravity or the
    # body draws it back to its length (``step``). Pushing back from the first step, the legs lengthened both
    # ways while the body grew with gravity off, lifting the waist 2 cm at the default step and 7.7 cm at a 4x
    # finer one: where the drape came to rest depended on the step.
    if folded is None:
        folded = (np.flatnonzero(folded_at(x, springs, rest, tuning.folded_below)) if initial is None
                  else np.empty(0, dtype=np.int64))
    folded = np.asarray(folded, dtype=np.int64)
    own[folded, 2] = 0.0

    collider = BodyCollider(body, settings.collision_margin)
    placed_tops = piece_tops(x, piece)  # to tell at the end how far the garment slid down
    # the sleeves' and trouser legs' openings, to tell at the end whether each is around its limb
    openings = limb_openings(x, model.coarse_faces, body, model.meta.category, model.coarse_loops, piece)
    arms = ArmSchedule(body, collider, plan, settings.time_step / REFERENCE_STEP) if motion is None else motion(collider)
    parts = relevant_parts(body.maps, x.min(axis=0), x.max(axis=0), tuning.part_reach)
    if arms.steps:
        arms.apply(0)
        arms.attach(x, model.coarse_faces)
        turned = arms.turned_parts()  # the sleeves are around them
        parts = np.union1d(parts, turned).astype(np.int64)

    # a tangled start: grow the body, or (growth off) push out and pin for a few steps
    tangled = bool((collider.depth(x, parts, offset=True) > 0).any())
    grow_steps = settings.steps_of(settings.grow_steps) if tangled else 0
    if grow_steps:
        collider.set_growing(growing_parts(collider, parts, tuning.grow_reach))
        collider.set_scale(settings.grow_from)
    state = DrapeState.at(x, inv_mass, started)
    state.table, state.folded = own, folded
    pinned_until, saved_inv_mass = 0, None
    if tangled and not grow_steps:
        collider.collide(x, state.x_prev, inv_mass, state.active, parts, settings.contact_offset, 0.0, 0.0,
                         state.contact)
        state.x_prev[:] = x
        state.x_checked[:] = x
        state.x_step[:] = x
        saved_inv_mass = inv_mass.copy()
        inv_mass[state.contact] = 0.0
        pinned_until = tuning.pin_steps

    floor_y = tuning.floor_y
    if tuning.floor_under_sole:
        # a floor inside the offset body (the soles are on y = 0, offset down by the margin) would trap a
        # trouser hem between the floor and the sole's rim, the collision pushing it down and the floor
        # pushing it back up, stretching its springs without end
        floor_y = min(floor_y, float(body.vertices[:, 1].min()) - settings.collision_margin
                      - settings.contact_offset)
    drape_model = DrapeModel(garment=model, settings=settings, tuning=tuning, packed=packed, openings=openings,
                             placed_tops=placed_tops, floor_y=floor_y, sized=sized)
    control = BodyControl(body=body, collider=collider, arms=arms, plan=plan, parts=parts, grow_steps=grow_steps,
                          startup=max(grow_steps, arms.steps), pinned_until=pinned_until,
                          saved_inv_mass=saved_inv_mass, moving=motion is not None)
    return Drape(drape_model, state, control)


def growing_parts(collider: BodyCollider, parts: np.ndarray, reach: float) -> np.ndarray:
    """The body parts of ``parts`` a tangled start grows (int64 indices): those whose vertices are at most
    ``reach`` times their median distance from the part's axis (``Tuning.grow_reach``; a foot, far from the
    shin's axis, is not grown)."""
    ratio = collider.reach_ratio()
    return np.array([k for k in parts if ratio[k] <= reach], dtype=np.int64)
