"""One try-on: align, then step (integrate, collide, constrain) until the garment is at rest.

State is flat arrays: positions x (k, 3), previous positions (k, 3), inverse masses (k,), the model's
springs (s, 2) / rest lengths (s,) / kinds (s,), strain limits per kind. Python only loops over steps and
substeps; every loop over particles or springs is a numba kernel.

One step (time_step dt) is ``substeps`` substeps of dt / substeps ("small steps": the passes spread over
substeps converge much further than the same passes on one step). Each substep:
1. Verlet prediction with gravity and air drag (eq. 1);
2. first substep only: collision against the offset body (paper 3.3-3.4, ``collision/``), which pushes
   points out (eq. 4) and leaves a contact plane for each point pushed or within ``NEAR`` of the body;
   contacts still within ``PLANE_REUSE`` of where they touched only reuse their plane (no map query);
   later substeps push onto the planes, with friction on the predicted motion; a point pinched between two
   parts (pushed out of each into the other: cloth between touching thighs) is held where the step began
   (``hold_pinched``, once the body no longer grows or turns), and one flipping between the parts is kept
   still through the step's substeps too (``PINCH_FLIP``);
3. the strain-limited springs (eq. 2-3), ``passes / substeps`` Gauss-Seidel passes, each followed by the
   contact planes (springs and contacts converge together);
4. the top-down sweep for hanging cloth (``sweep_downward``: a sagging free end follows the point above
   it; springs with both ends on the body are left to the contact passes), the planes again, then
   Coulomb friction from the summed contact pushes (a band's hoop tension on the hips is what holds a
   skirt up) and the floor.
After the step a guard keeps every spring under ``TEAR_GUARD`` x its natural length (never active in a
normal drape; it keeps a garment far too small for its body from being stretched without bound).

Start-up, for garments that begin tangled with the body (sleeves at another angle than the arms, a
garment modelled on another body):
- the arms are posed along the sleeves (``plan_arms``) and turned back to their real pose over the first
  steps (``arms.ArmSchedule``), carrying the sleeves with them, instead of cutting through them;
- if any garment point is still inside the body, the body grows from ``grow_from`` of its radius to full
  size over ``grow_steps`` steps (each part scaled toward its axis; Houdini Vellum Drape does the same),
  pushing the cloth out the way it came in rather than teleporting points through the body;
- during these start-up steps gravity is off: a garment held by shoulders or hips would otherwise slide
  down a body that is not yet its full size. It falls into place once the body is complete;
- the paper instead pushes such points out and pins them; pinning them for good would hold the garment
  unnaturally, so when growth is disabled (grow_steps = 0) pushed points are pinned only for the first
  ``PIN_STEPS`` steps and then released.

Points at rest cost almost nothing: a point that moved less than ``REST_MOVE`` since it was last found
outside the (static) body, and is not in contact, cannot be inside it by more than that, so its
collision test is skipped; a contact at rest only re-projects onto its plane.

After the loop, a relaxation: the same substeps with gravity and friction off and light drag, from rest, until
every spring meets the strain target (or progress stalls, or ``MAX_POLISH_ROUNDS`` steps). At rest under
gravity the Gauss-Seidel passes leave the springs that hold the garment up (a waistband on the hips, cloth
over the shoulders) a few % over their limits, and a band that sagged too low cannot shorten without climbing
back up the body, a coordinated motion that damped passes make only a little of per round (hundreds of
rounds). Without gravity the over-long springs are the only force left (and only they act: stretch-only, so no
compression pushes cloth up off the body); with little drag the motion they start is kept (momentum: the
heavy-ball acceleration of an iterative solver), so the band climbs to where it fits in 10-40 rounds. The
garment moves only as far as its over-stretch asks: on the medium body a median 1-6 mm per point and up to 1-3
cm, but up to 7-10 cm where a long sleeve or a trouser hem was stretched along the limb and shortens up it.
A garment far too small for the body has no such place nearby, and the relaxation carries it off (a blouse up
around the neck, trousers down to the knees): for each piece of the file of which it moved a tenth of the
points more than ``RELAX_MAX_MOVE`` it is dropped, and the loop's result for that piece is kept with its
springs over the target reported (metrics ``relaxed``, ``relax_move_mm``: the largest piece's 90th
percentile move, the largest move). Then the full mesh is rebuilt from the coarse one (``full_mesh``: the
re-attachment, a few stretch passes over the full mesh's own springs, and its vertices pushed out of the
offset body too), so the displayed mesh neither stretches beyond the cloth nor penetrates.

The floor (y = ``FLOOR_Y``) is put under the offset body's soles, so a trouser hem on the floor beside a
foot is not caught between the floor and the sole's offset rim.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from tryon.body.types import Body
from tryon.garment.model import GarmentModel
from tryon.garment.springs import STRUCTURAL
from tryon.sim.align import ArmPlan, align_sized, plan_arms
from tryon.sim.arms import ArmSchedule
from tryon.sim.collision.collider import BodyCollider
from tryon.sim.collision.collider import relevant_parts
from tryon.sim.collision.contacts import flipped, points_to_test, reuse_planes
from tryon.sim.full_mesh import display_strain, follow_coarse
from tryon.sim.show_through import show_through_depth, show_through_metrics
from tryon.sim.limbs import limb_openings, openings_on_limbs
from tryon.sim.pieces import hanging_pieces, piece_labels, piece_tops, waistband_mask
from tryon.sim.constraints import (
    cap_stretch, contact_springs, pack_springs, pack_sweep, solve_listed, spring_lengths, sweep_springs,
    top_down_order,
)
from tryon.sim.integrate import kinetic_energy_per_kg, verlet_step
from tryon.sim.metrics import (
    allowed_length, penetration_metrics, slid_metrics, strain_metrics, too_tight_places,
)
from tryon.sim.settings import SimSettings
from tryon.sim.substeps import finish_relaxation_round, finish_step

# m: a point that moved less than this since its last collision test (and was not in contact) is not
# tested again: the body is static, so it is still outside the offset body, i.e. >= margin - 0.1 mm
# clear of the real one.
REST_MOVE = 1e-4
# m: how far beyond the aligned garment's bounding box a body part must be to be never tested (the
# garment can fall or slide a little; a part further than this cannot be reached before rest).
PART_REACH = 0.15
# Steps for which points pushed out at alignment stay pinned when growth is off (see module doc).
PIN_STEPS = 5
# The relaxation after the loop (see the module doc): at least MIN rounds (one step's substeps each), then
# until every spring meets the strain target (``metrics.allowed_length``), at most MAX, and given up when
# the count of springs over the target has not fallen to PROGRESS x its lowest in STALL rounds (a garment
# too small for the body there: its springs stay over whatever the rounds). Over the 54 catalogue drapes
# (18 garments x small / medium / large bodies) the springs over the target fell from 623 / 792 / 6439
# with the earlier polish (60 rounds of collision + passes + a top-down lift, no momentum) to 33 / 258 /
# 6258 with this at most 60 rounds. A band that must stretch a little to sit on a large body climbs
# slowly: the L skirt and shorts on the large body need 81 and 193 rounds; with at most 300 and the stall
# rule they meet the target, and the drapes that cannot (S / M garments on the large body) stop after
# 33-67 rounds (``tryon bench --only fit``).
MIN_POLISH_ROUNDS = 3
MAX_POLISH_ROUNDS = 300
POLISH_STALL_ROUNDS = 30
POLISH_PROGRESS = 0.9
# 1/s, air drag in the relaxation: light, so the motion the constraints start keeps going (a waistband
# climbs back up to where it fits in 10-40 rounds instead of hundreds of passes without momentum), yet a
# cloth pulled up off a table by the springs at its rim comes to a stop (0 and 10/s left bumps of 2 mm
# and 1.7 cm on the table test at 0.05 s; 20/s: 0.2 mm).
RELAX_DRAG = 20.0
# The relaxation is kept for each piece of the file that it moved less than RELAX_MAX_MOVE (m) at the
# RELAX_MOVE_QUANTILE of the piece's coarse points. A garment far too small for its body has no nearby place
# where its springs meet the target, and without gravity the relaxation carries it to wherever they come
# closest: a MakeHuman blouse on the medium body ended up bunched around the neck (90 % of its points
# moved up to 55 cm), a 92 cm DiffCloth dress as a crumpled smock (49 cm), MakeHuman trousers down to the
# knees (26 cm: their legs stayed, so the median point moved only 5 cm). The catalogue's 54 drapes move
# 90 % of their points at most 12 cm (the large body in S shorts and long sleeves), most under 2 cm.
RELAX_MOVE_QUANTILE = 0.9
RELAX_MAX_MOVE = 0.15
# Steps between re-sorting the springs from the top down for the hanging-stretch sweep (the garment's
# vertical order changes slowly once it hangs).
ORDER_REFRESH = 20
# m: points outside the offset body but closer than this get a contact plane for the step's constraint
# passes (so the springs cannot pull them in between two collision tests).
NEAR = 0.005
# m: a contact plane is reused (no map query) while the point stays this close to where it touched.
PLANE_REUSE = 0.01
# m: a point held in a pinch (see the module doc) whose last two steps moved it more than this each, the
# second back against the first, is flipping between the two parts (the springs moving it through one and
# back every other step; ~5 cm under the armpit of the long-sleeve M with the arm at 15 degrees, the elbow
# bent 100, which never came to rest): it is kept still, springs included, for as long as it stays
# pinched. Only once the garment has fallen (after the start-up and ``min_steps``): holding every pinched
# point still, or every one that moved over 1 cm, or flipping ones from the start, left a sleeveless dress's
# armhole off the arm with the arms hanging, its cloth caught while falling, and a long-sleeve L with the
# elbow bent 120 not at rest (``tryon bench --only poses``); flips over 1 cm left 26 springs over on the
# T-shirt M with the elbow bent 120, over 3 cm the long-sleeve L at 15 degrees still flipping.
PINCH_FLIP = 0.02
# m: the floor the body stands on (its feet are on y = 0); trouser legs and long hems rest on it.
FLOOR_Y = 0.001
# Whether the floor is put under the offset body's soles (see ``drape``).
FLOOR_UNDER_SOLE = True
# Whether the top-down stretch sweep runs after every substep (True) or once per step (False: half the
# cost, but bottoms then slide off the hips: measured on the catalogue). After every second substep: the
# 90 catalogue drapes need 17-23 % more steps.
FTL_EVERY_SUBSTEP = True
# Largest spring length / natural length the step's last sweeps allow (issue 5: never beyond 3x), and
# at most how many such sweeps (they stop as soon as one finds nothing to do).
TEAR_GUARD = 2.5
TEAR_PASSES = 100
# Inverse-mass factor of points in contact during the constraint passes (see the loop).
CONTACT_WEIGHT = 0.2
# Extra Gauss-Seidel passes per substep over the springs with both ends on the body (a waistband around
# the hips, a bodice over the chest), stretch only: their hoop tension is what holds a garment up, and
# with one pass of the whole cloth per substep it stretched 15-25 % before friction held it, so bottoms
# came to rest 1-2 cm too low, beyond their limits. One pass rather than two: as accurate on the catalogue
# and the real garments, with fewer steps to rest (two kept some real garments from rest); none: the
# drapes need 3-7 % more steps and leave springs over on the large body (`tryon bench --only fit`).
CONTACT_PASSES = 1

FrameCallback = Callable[[int, np.ndarray], bool]


@dataclass
class TryOnResult:
    """vertices (n, 3) full mesh, m; strain (n,) per full vertex; coarse (k, 3) simulated positions;
    metrics dict (steps, sim_seconds, wall_seconds, rest_reached, penetrating_vertices,
    max_penetration_mm, max_strain, strain_by_kind, too_tight (``metrics.too_tight_places``), ...)."""

    vertices: np.ndarray
    faces: np.ndarray
    strain: np.ndarray
    coarse: np.ndarray
    metrics: dict = field(default_factory=dict)


def drape(body: Body, model: GarmentModel, settings: SimSettings = SimSettings(),
          on_frame: FrameCallback | None = None, initial: np.ndarray | None = None) -> TryOnResult:
    """Drape ``model`` on ``body``; see the module doc. ``initial`` (k, 3) replaces the alignment
    (tests and stress scenes start from given positions)."""
    t_start = time.perf_counter()
    sized = False
    piece = piece_labels(model.coarse_faces, len(model.mass))  # a file's separate garments (an outfit's)
    if initial is None:
        x, shape = align_sized(body, model, piece=piece)
        sized = shape is not None
        if sized:  # sized to this body (guessed units): its springs' natural lengths change too
            model = model.resized(shape)
        plan = plan_arms(body, x, model.meta.category, model.coarse_faces, model.coarse_loops, piece)
    else:
        x = np.array(initial, dtype=np.float64)
        plan = ArmPlan(0.0, 0.0)
    dt = float(settings.time_step)
    limits = settings.limits_array()
    compression = settings.compression_array()
    springs = np.ascontiguousarray(model.springs, dtype=np.int64)
    rest = np.ascontiguousarray(model.rest, dtype=np.float64)
    kind = np.ascontiguousarray(model.kind, dtype=np.int64)
    mass = np.ascontiguousarray(model.mass, dtype=np.float64)
    inv_mass = np.where(mass > 0, 1.0 / np.where(mass > 0, mass, 1.0), 0.0)
    ends, table = pack_springs(springs, rest, kind, limits, compression)
    # a bottom's waistband stretches less than its cloth (``band_limit``; its structural springs: the
    # band's hoop and height). Only the solver holds it so: the metrics judge each spring by its type's
    # limit, so a band too small for its waist shows springs over where it is stretched past the cloth's.
    band = waistband_mask(model.coarse_vertices, model.coarse_faces, model.meta.category, model.coarse_loops,
                          piece)
    band_springs = (kind == STRUCTURAL) & band[springs[:, 0]] & band[springs[:, 1]]
    table[band_springs, 0] = rest[band_springs] * (1.0 + settings.band_limit)

    collider = BodyCollider(body, settings.collision_margin)
    placed_tops = piece_tops(x, piece)  # to tell at the end how far the garment slid down
    # the sleeves' and trouser legs' openings, to tell at the end whether each is around its limb
    openings = limb_openings(x, model.coarse_faces, body, model.meta.category, model.coarse_loops, piece)
    arms = ArmSchedule(body, collider, plan)
    lo, hi = x.min(axis=0), x.max(axis=0)
    parts = relevant_parts(body.maps, lo, hi, PART_REACH)
    if arms.steps:
        arms.apply(0)
        arms.attach(x, model.coarse_faces)
        turned = arms.turned_parts()  # the sleeves are around them
        parts = np.union1d(parts, turned).astype(np.int64)

    # --- tangled start: grow the body, or (growth off) push out and pin for a few steps
    tangled = bool((collider.depth(x, parts, offset=True) > 0).any())
    grow_steps = settings.grow_steps if tangled else 0
    pinned_until = 0
    if grow_steps:
        collider.set_scale(settings.grow_from)
    x_prev = x.copy()
    contact = np.zeros(len(x), dtype=np.bool_)
    active = np.ones(len(x), dtype=np.bool_)
    if tangled and not grow_steps:
        collider.collide(x, x_prev, inv_mass, active, parts, settings.contact_offset, 0.0, 0.0, contact)
        x_prev[:] = x
        saved_inv_mass = inv_mass.copy()
        inv_mass[contact] = 0.0
        pinned_until = PIN_STEPS
    x_checked = x.copy()
    x_step = x.copy()
    reused = np.zeros(len(x), dtype=np.bool_)
    push = np.zeros(len(x))
    has_plane = np.zeros(len(x), dtype=np.bool_)
    planes = (has_plane, np.zeros((len(x), 3)), np.zeros((len(x), 3)))
    held = np.zeros(len(x), dtype=np.bool_)  # held in a pinch between two parts this step
    flipping = np.zeros(len(x), dtype=np.bool_)  # held, and flipping between them: kept still (PINCH_FLIP)
    moves = np.zeros((2, len(x), 3))  # m, each point's move in the step before and in the one before that

    startup = max(grow_steps, arms.steps)
    # the contact passes' and the sweep's springs, chosen each step once the body is complete
    body_ends, body_table = np.empty((0, 2), dtype=np.uint32), np.empty((0, 4))
    sweep_ends, sweep_lmax = np.empty((0, 2), dtype=np.uint32), np.empty(0)
    # substeps ("small steps", Macklin et al. 2019): the passes are spread over substeps of the time step,
    # which converges much further per pass than repeating passes on one large step
    n_sub = max(1, min(settings.substeps, settings.passes))
    per_sub = max(1, settings.passes // n_sub)
    h = dt / n_sub
    mu_s, mu_k = settings.friction_static, settings.friction_kinetic
    # the floor lies under the offset body's soles: a floor inside the offset body (the soles are on
    # y = 0, offset down by the margin) would trap a trouser hem between the floor and the sole's rim,
    # the collision pushing it down and the floor pushing it back up, stretching its springs without end
    floor_y = FLOOR_Y
    if FLOOR_UNDER_SOLE:
        floor_y = min(FLOOR_Y, float(body.vertices[:, 1].min()) - settings.collision_margin - settings.contact_offset)
    rest_run = 0
    rest_reached = False
    step = 0
    stopped = False
    energy = 0.0
    collided = 0
    for step in range(1, settings.max_steps + 1):
        changing = step <= startup
        turning = bool(arms.steps) and step <= arms.steps + 1
        if grow_steps and step <= grow_steps + 1:
            s = settings.grow_from + (1.0 - settings.grow_from) * min(1.0, step / grow_steps)
            collider.set_scale(s, refresh=not turning)  # the arms' turn recomputes the surface anyway
        if turning:
            arms.apply(step)
            arms.carry(x, x_prev)
        if pinned_until and step == pinned_until:
            inv_mass[:] = saved_inv_mass
        # no gravity while the body grows / the arms turn back: the garment must not slide off a body
        # that is not yet its full size (the fit phase); it falls once the body is complete
        gravity = 0.0 if changing else settings.gravity
        # the first substep's prediction, collision and passes here; its tail and the other substeps in
        # one kernel (``finish_step``)
        verlet_step(x, x_prev, inv_mass, h, gravity, settings.air_drag, settings.max_speed)
        # collision (paper 3.3-3.4) on the predicted positions, leaving a contact plane for every point
        # pushed out or lying within NEAR of the body; the substeps keep to those planes
        if changing:
            active[:] = True
        else:
            # contacts still near where they touched keep their plane (no map query), points that have not
            # moved since their last test and touch nothing are not tested at all
            reuse_planes(x, x_prev, *planes, PLANE_REUSE, mu_s, mu_k, contact, reused)
            points_to_test(x, x_checked, has_plane, reused, REST_MOVE, active)
            active |= held
        collided = collider.collide(x, x_prev, inv_mass, active, parts, settings.contact_offset, mu_s, mu_k,
                                    contact, near=NEAR, planes=planes, hold_pinched=not changing, held=held)
        x_checked[active] = x[active]
        touching = np.flatnonzero(has_plane)  # the points with a contact plane this step
        # a point flipping in a pinch stays still for the whole step, springs included (PINCH_FLIP)
        flipping &= held
        if held.any() and step > startup + settings.min_steps:
            flipping |= held & flipped(moves[0], moves[1], PINCH_FLIP)
        step_mass = np.where(flipping, 0.0, inv_mass) if flipping.any() else inv_mass
        # points on the body count as heavier in the springs, so hanging cloth hangs from them instead of
        # dragging them in (mass scaling)
        w_eff = np.where(has_plane, step_mass * CONTACT_WEIGHT, step_mass)
        contact_passes = CONTACT_PASSES if not changing else 0
        if contact_passes:
            body_ends, body_table = contact_springs(ends, table, has_plane)
        solve_listed(x, x_prev, w_eff, ends, table, per_sub, touching, planes[1], planes[2], 0.0, 0.0, push)
        if contact_passes:
            solve_listed(x, x_prev, w_eff, body_ends, body_table, contact_passes, touching, planes[1], planes[2],
                         0.0, 0.0, push)
        if step % ORDER_REFRESH == 1:
            ordered_ends, ordered_lmax = pack_sweep(ends, table, top_down_order(x, springs))
        if not changing:
            sweep_ends, sweep_lmax = sweep_springs(ordered_ends, ordered_lmax, has_plane,
                                                   hanging_pieces(piece, has_plane | (inv_mass == 0.0)))
        # the top-down sweep is for cloth hanging under gravity; without gravity (growth) its upward bias
        # would make a tight garment climb off the body
        finish_step(x, x_prev, step_mass, w_eff, h, gravity, settings.air_drag, settings.max_speed, n_sub, per_sub,
                    ends, table, contact_passes, body_ends, body_table, touching, planes[1], planes[2], has_plane,
                    push, mu_s, mu_k, not changing, FTL_EVERY_SUBSTEP, sweep_ends, sweep_lmax, floor_y)
        # guard: collision wins over the springs within the step, so a garment far too small for its
        # body (a size S shirt on the largest body) would be stretched without bound; past TEAR_GUARD x
        # its natural length a spring wins instead (the point may stay inside the body: the metrics
        # report it). Never active in a normal drape, whose springs stay within their limits.
        cap_stretch(x, inv_mass, springs, rest, TEAR_GUARD, TEAR_PASSES)
        # at rest = the garment's own motion over the last two steps (positions, not the solver's internal
        # velocities, which the strain limits and contact planes keep resetting). Over two steps, because a
        # point caught between the collision and its springs can flip between two places every step, going
        # nowhere: three such points at the armpit of the DiffCloth dress on the large body (2-3 cm a step)
        # kept it from rest for 400 steps. Over two steps, the 27 real-garment drapes all come to rest
        # (25 before) in 1,800 steps instead of 2,433; the 90 catalogue drapes in 6,313 instead of 6,487.
        moves[1] = moves[0]
        np.subtract(x, x_step, out=moves[0])
        # x_step - moves[1]: where each point was two steps before (at step 1: where it started)
        energy = kinetic_energy_per_kg(x, x_step - moves[1], mass, 2 * dt if step > 1 else dt)
        x_step[:] = x
        if not np.isfinite(energy):
            raise FloatingPointError(f"simulation diverged at step {step}")
        if step > startup and step >= settings.min_steps and energy < settings.rest_energy:
            rest_run += 1
            if rest_run >= settings.rest_steps:
                rest_reached = True
        else:
            rest_run = 0
        if on_frame is not None and on_frame(step, x) is False:
            stopped = True
            break
        if rest_reached:
            break

    # --- make sure the body is at full size and pose, then polish (constraints + collision)
    if collider.scale != 1.0:
        collider.set_scale(1.0, refresh=not arms.steps)
    if arms.steps:
        arms.apply(arms.steps)
    if pinned_until and step < pinned_until:
        inv_mass[:] = saved_inv_mass
    # relaxation: the garment at rest, with gravity and friction off and light drag (see the module doc)
    target = allowed_length(rest, limits[kind])
    polish_rounds = 0
    x_prev[:] = x
    x_loop = x.copy()
    stretch_only = table.copy()
    # only the over-long springs act: no compression pushes cloth off the body (and with l0 = 0 too a
    # compressed spring is not even visited for a zero correction: same result, the relaxation's passes
    # skip the buckled cloth on the body)
    stretch_only[:, 1:] = 0.0
    fewest_over, best_round = len(springs) + 1, 0
    for polish_rounds in range(1, MAX_POLISH_ROUNDS + 1):
        # the first substep's prediction and collision here, the rest of the round in one kernel
        verlet_step(x, x_prev, inv_mass, h, 0.0, RELAX_DRAG, settings.max_speed)
        active[:] = True
        collider.collide(x, x_prev, inv_mass, active, parts, settings.contact_offset, 0.0, 0.0, contact, near=NEAR,
                         planes=planes)
        touching = np.flatnonzero(has_plane)
        finish_relaxation_round(x, x_prev, inv_mass, h, RELAX_DRAG, settings.max_speed, n_sub, per_sub, ends,
                                stretch_only, touching, planes[1], planes[2], push, floor_y)
        cap_stretch(x, inv_mass, springs, rest, TEAR_GUARD, TEAR_PASSES)
        if polish_rounds >= MIN_POLISH_ROUNDS:
            # judged after the final collision the result gets (between two collision tests a point may
            # slide past its contact plane, over a sharp edge, and be pushed back out, stretching springs)
            active[:] = True
            collider.collide(x, x_prev, inv_mass, active, parts, settings.contact_offset, 0.0, 0.0, contact)
            n_over = int(np.count_nonzero(spring_lengths(x, springs) > target))
            if n_over == 0:
                break
            if n_over <= POLISH_PROGRESS * fewest_over:
                fewest_over, best_round = n_over, polish_rounds
            elif polish_rounds - best_round >= POLISH_STALL_ROUNDS:
                break  # no progress: a garment too small for the body there (its springs stay over)
    else:  # out of rounds: the last positions still get their final collision
        active[:] = True
        collider.collide(x, x_prev, inv_mass, active, parts, settings.contact_offset, 0.0, 0.0, contact)
    relax_move = np.linalg.norm(x - x_loop, axis=1)  # m, per coarse point: how far the relaxation moved it
    # each piece of the file on its own (pieces meet only the body, never each other): an outfit's
    # trousers may be carried down the legs while its shirt barely moves
    piece_move = np.array([np.quantile(relax_move[piece == p], RELAX_MOVE_QUANTILE)
                           for p in range(int(piece.max()) + 1)])
    carried = piece_move > RELAX_MAX_MOVE
    # nor may it take a sleeve or trouser leg off its limb (a T-shirt on arms hanging against the torso:
    # the sleeves, pinched between arm and torso, pulled up off the arms)
    for (_, _, loop), before, after in zip(openings, openings_on_limbs(x_loop, body, openings),
                                           openings_on_limbs(x, body, openings)):
        if before["ok"] and not after["ok"]:
            carried[piece[loop[0]]] = True
    relaxed = not carried.any()
    if not relaxed:
        # the relaxation carried a piece away (see RELAX_MAX_MOVE): that piece stays where the loop
        # left it, its springs over the target reported as they are
        back = carried[piece]
        x[back] = x_loop[back]
        x_prev[:] = x
        active[:] = True
        collider.collide(x, x_prev, inv_mass, active, parts, settings.contact_offset, 0.0, 0.0, contact)

    # the tear guard again: the final collision wins over the springs, so a garment far too small for its
    # body would leave it with springs pushed past TEAR_GUARD (the loop's guard ran before it)
    cap_stretch(x, inv_mass, springs, rest, TEAR_GUARD, TEAR_PASSES)

    # --- full mesh: follow the coarse one, its stretch held to the limits, pushed out of the offset body
    full, full_parts = follow_coarse(model, x, collider, limits, settings.contact_offset, floor_y)

    # --- metrics
    depth = collider.depth(full, full_parts, offset=False)
    spring_strain_, per_vertex, by_kind = strain_metrics(x, model, limits, on_body=has_plane.copy())
    too_tight = too_tight_places(x, model, spring_strain_, limits, has_plane, body)
    on_limbs = openings_on_limbs(x, body, openings)
    wall = time.perf_counter() - t_start
    metrics = {
        "steps": int(step),
        "sim_seconds": float(step * dt),
        "wall_seconds": float(wall),
        "rest_reached": bool(rest_reached),
        "stopped": bool(stopped),
        **penetration_metrics(depth),
        **show_through_metrics(show_through_depth(collider, full_parts, full, model.faces)),
        "max_strain": float(spring_strain_.max()) if len(spring_strain_) else 0.0,
        "display_max_strain": display_strain(full, model),
        "strain_by_kind": by_kind,
        "too_tight": too_tight,
        "limb_openings": on_limbs,
        "openings_on_limbs": all(o["ok"] for o in on_limbs) if on_limbs else None,
        **slid_metrics(placed_tops, x, piece),
        "sized_to_body": sized,
        "kinetic_energy_per_kg": float(energy),
        "grown": bool(grow_steps),
        "arm_turn_deg": [float(np.degrees(plan.left)), float(np.degrees(plan.right))],
        "elbow_turn_deg": [float(np.degrees(plan.left_elbow)), float(np.degrees(plan.right_elbow))],
        "parts_tested": [body.parts[k] for k in parts],
        "last_step_contacts": int(collided),
        "polish_rounds": int(polish_rounds),
        "relax_move_mm": [float(1000 * piece_move.max()), float(1000 * relax_move.max())],
        "relaxed": bool(relaxed),
        "pose": dict(body.pose),
    }
    return TryOnResult(vertices=full, faces=model.faces, strain=per_vertex, coarse=x, metrics=metrics)
