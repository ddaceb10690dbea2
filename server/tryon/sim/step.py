"""One time step of a drape: the body's start-up change, Verlet, collision, the substeps' passes, the fast
projection of the strain limits if asked for, the guards.

See ``run.py``'s doc for the method. ``step`` advances ``drape.state`` in place and tells whether the
garment has come to rest; it works from whatever state it is given (a fresh ``start`` or a drape that has
already run), so a caller may step a drape on for as long as it likes.
"""

from __future__ import annotations

import numpy as np

from tryon.sim.blocks import block_order
from tryon.sim.collision.contacts import (
    points_to_test, project_listed, reuse_planes, take_stricter_planes,
)
from tryon.sim.collision.self_contact import keep_drape_sides
from tryon.sim.collision.untangle import untangle
from tryon.sim.constraints import (
    cap_stretch, contact_springs, pack_sweep, solve_listed, sweep_springs, top_down_order,
)
from tryon.sim.integrate import kinetic_energy_per_kg, verlet_step
from tryon.sim.pieces import hanging_pieces
from tryon.sim.projection import project_stretch, sticking
from tryon.sim.state import Drape
from tryon.sim.substeps import Planes, Springs, Substeps, Sweep, finish_step


def step(d: Drape) -> bool:
    """Advance ``d.state`` by one time step; True once the garment is at rest (``settings.rest_energy`` for
    ``settings.rest_steps`` steps, after the start-up and ``settings.min_steps``). Raises FloatingPointError
    if the simulation diverged."""
    s, st, tu, collider, arms = d.settings, d.state, d.tuning, d.collider, d.arms
    x, x_prev, inv_mass = st.x, st.x_prev, st.inv_mass
    st.step += 1
    n = st.step
    changing = n <= d.startup
    turning = bool(arms.steps) and n <= arms.steps + 1
    if d.grow_steps and n <= d.grow_steps + 1:
        scale = s.grow_from + (1.0 - s.grow_from) * min(1.0, n / d.grow_steps)
        collider.set_scale(scale, refresh=not turning)  # the arms' turn recomputes the surface anyway
    if turning:
        arms.apply(n)
        arms.carry(x, x_prev)
    if d.pinned_until and n == d.pinned_until:
        inv_mass[:] = d.saved_inv_mass
    # no gravity while the body grows / the arms turn back: the garment must not slide off a body that is
    # not yet its full size (the fit phase); it falls once the body is complete
    gravity = 0.0 if changing else s.gravity
    mu_s, mu_k = s.friction_static, s.friction_kinetic
    # the first substep's prediction, collision and passes here; its tail and the other substeps in one
    # kernel (``finish_step``)
    verlet_step(x, x_prev, inv_mass, d.h, gravity, s.air_drag, s.max_speed)
    # a re-posed drape does not leave a pinched point deeper in the body than the collision's reach within a
    # step (``collide_points``' hold_depth); a drape from scratch holds it wherever it is
    hold_depth = d.reach if d.moving else 1e9
    # collision (paper 3.3-3.4) on the predicted positions, leaving a contact plane for every point pushed
    # out or lying within ``near`` of the body; the substeps keep to those planes
    if changing:
        st.active[:] = True
    else:
        # contacts still near where they touched keep their plane (no map query), points that have not moved
        # since their last test and touch nothing are not tested at all
        reuse_planes(x, x_prev, *st.planes, tu.plane_reuse, mu_s, mu_k, st.contact, st.reused)
        points_to_test(x, st.x_checked, st.has_plane, st.reused, tu.rest_move, st.active)
        st.active |= st.held
    st.collided = collider.collide(x, x_prev, inv_mass, st.active, d.parts, s.contact_offset, mu_s, mu_k,
                                   st.contact, near=tu.near, planes=st.planes, hold_pinched=not changing,
                                   held=st.held, hold_depth=hold_depth, two=bool(d.blocks[2]))
    st.x_checked[st.active] = x[st.active]
    if st.layer_has.any():
        take_stricter_planes(x, *st.planes, *st.layer_planes)
    touching = np.flatnonzero(st.has_plane)  # the points with a contact plane this step
    # points on the body count as heavier in the springs, so hanging cloth hangs from them instead of
    # dragging them in (mass scaling)
    w_eff = np.where(st.has_plane, inv_mass * tu.contact_weight, inv_mass)
    contact_passes = tu.contact_passes if not changing else 0
    if contact_passes:
        d.body_ends, d.body_table, d.body_blocks = contact_springs(d.ends, d.table, st.has_plane, d.blocks)
    solve_listed(x, x_prev, w_eff, d.ends, d.table, d.per_sub, touching, st.plane_point, st.plane_normal, 0.0, 0.0,
                 st.push, 1.0, d.blocks)
    if contact_passes:
        solve_listed(x, x_prev, w_eff, d.body_ends, d.body_table, contact_passes, touching, st.plane_point,
                     st.plane_normal, 0.0, 0.0, st.push, 1.0, d.body_blocks)
    if n % tu.order_refresh == 1:
        order, d.ordered_blocks = block_order(top_down_order(x, d.springs), d.blocks)
        d.ordered_ends, d.ordered_lmax = pack_sweep(d.ends, d.table, order)
    if not changing:
        hangs = hanging_pieces(d.piece, st.has_plane | (inv_mass == 0.0))
        d.sweep_ends, d.sweep_lmax, d.sweep_blocks = sweep_springs(d.ordered_ends, d.ordered_lmax, st.has_plane,
                                                                   hangs, d.ordered_blocks)
    planes = Planes(touching, st.plane_point, st.plane_normal, st.has_plane, st.push)
    # the top-down sweep is for cloth hanging under gravity; without gravity (growth) its upward bias would
    # make a tight garment climb off the body (sweep: not changing)
    run = Substeps(float(d.h), int(d.n_sub), int(d.per_sub), int(contact_passes), float(gravity), float(s.air_drag),
                   float(s.max_speed), float(mu_s), float(mu_k), not changing, bool(tu.sweep_every_substep),
                   float(d.floor_y))
    movers = d.collider.movers(st, d.parts, s.contact_offset, tu.near, d.reach,
                               hold_pinched=not changing, retest_planes=d.moving, hold_depth=hold_depth,
                               two=bool(d.blocks[2]))
    finish_step(x, x_prev, inv_mass, w_eff, Springs(d.ends, d.table, d.blocks),
                Springs(d.body_ends, d.body_table, d.body_blocks), Sweep(d.sweep_ends, d.sweep_lmax, d.sweep_blocks),
                planes, run, movers)
    if s.projection_steps and not changing:
        _project(d, w_eff)
    if tu.self_thickness:
        keep_drape_sides(d, st.x_step, np.where(st.held, 0.0, w_eff))
    # not while the body changes: the start-up's arms' turn carries sleeves through the torso's cloth on purpose
    # (untangled then, the hanging-sleeve long-sleeve's cuffs ended round the upper arms), a re-pose's motion
    # crushes cloth in a bending elbow's crook
    if tu.untangle_step and tu.untangle_every and n % tu.untangle_every == 0 and not (changing or d.moving):
        untangle(d)
    if not changing or d.moving:  # a re-pose's start-up is the body's motion, shown: its frames too
        _out_of_the_body(d)
    # guard: collision wins over the springs within the step, so a garment far too small for its body (a
    # size S shirt on the largest body) would be stretched without bound; past ``tear_guard`` x its natural
    # length a spring wins instead (the point may stay inside the body: the metrics report it). In a normal
    # drape only a few short springs reach it for a few steps (of the catalogue's M garments on the three
    # bodies: the long-sleeve M's cuffs round the hands on the medium body, the trousers M's hem caught under a
    # sole there), and a re-pose's straddled limbs.
    cap_stretch(x, inv_mass, d.springs, d.rest, tu.tear_guard, tu.tear_passes)
    return _at_rest(d)


def _out_of_the_body(d: Drape) -> None:
    """The end of a step's substeps: every contact point more than ``tuning.frame_depth`` inside the real
    body goes out of it (frictionless, no velocity from the move), so the frame this step shows has none.

    Within the substeps a contact point only keeps to its plane, which holds it off the part it touched at
    the step's collision test, not off another part there: where two parts overlap (torso and thigh at the
    hip, upper arm and forearm at a bent elbow) a point sliding along its torso plane went up to 12.5 mm into
    the thigh (of the 90 catalogue drapes, 42 showed a frame more than 2 mm inside the body). Testing only
    points with a plane is enough: one without a plane that moved more than the margin plus ``frame_depth``
    since its test was tested again within the substeps (``collision.movers``). A point pinched between two
    parts (``held``) keeps its place, as ``hold_pinched`` asks (pushed on it would flip between the parts), and
    goes back to it if the springs drew it in (``_held_back``); one pushed out of one part into another ends
    where the pushes leave it least deep (``collide_points``' hold_depth). Before the tear guard: a garment far
    too small for its body is still let into it there. Not while a drape from scratch starts up (the body grows
    round the cloth, unseen), but in every step of a re-pose, whose start-up frames show the body moving. Nor on
    a body of one part (the bench's ball): there is no other part to slide into, and the test would cost 9 % of
    the ball's steps."""
    if len(d.parts) < 2:
        return
    st, tu = d.state, d.tuning
    _held_back(d)
    touching = np.flatnonzero(st.has_plane & ~st.held)
    deep = touching[d.collider.depth(st.x[touching], d.parts, two=bool(d.blocks[2])) > tu.frame_depth]
    if len(deep) == 0:
        return
    st.active[:] = False
    st.active[deep] = True
    d.collider.collide(st.x, st.x_prev, st.inv_mass, st.active, d.parts, d.settings.contact_offset, 0.0, 0.0,
                       st.contact, near=tu.near, planes=st.planes, held=np.zeros(len(st.x), dtype=np.bool_),
                       hold_depth=d.reach)
    st.x_checked[deep] = st.x[deep]


def _held_back(d: Drape) -> None:
    """Every point held in a pinch between two parts (``collide_points``' ``hold_pinched``: pushed out of each it
    would flip between them) that the step's springs drew more than ``tuning.frame_depth`` into the body, deeper
    than where it began the step, goes back there, at rest. The pinch holds it where the step began, but within
    the substeps its springs still move it: a crotch point of the small body's trousers XL, between the thighs,
    was drawn 10.3 mm into the right one in a shown frame (``tryon bench --only fit``: 4 of the 90 drapes showed
    such a frame: the small body's trousers M, XL, XXL and the medium body's XXL)."""
    st, tu = d.state, d.tuning
    held = np.flatnonzero(st.held)
    if len(held) == 0:
        return
    now = d.collider.depth(st.x[held], d.parts)
    deep = now > tu.frame_depth
    if not deep.any():
        return
    drawn = held[deep]
    back = drawn[d.collider.depth(st.x_step[drawn], d.parts) < now[deep]]
    st.x[back] = st.x_step[back]
    st.x_prev[back] = st.x_step[back]


def _project(d: Drape, w_eff: np.ndarray) -> None:
    """The step's fast projection of the strain limits (``projection.py``), ``settings.projection_steps``
    Newton steps, with the passes' weights ``w_eff`` (k,) 1/kg; positions only (x_prev moves with x), then
    the contact planes again."""
    st = d.state
    w = np.empty_like(w_eff)
    sticking(st.x, st.x_step, w_eff, st.has_plane, st.plane_normal, w)
    before = st.x.copy()
    project_stretch(st.x, w, d.ends, d.table, st.has_plane, st.plane_normal, d.settings.projection_steps, d.blocks)
    st.x_prev += st.x - before
    project_listed(st.x, st.x_prev, np.flatnonzero(st.has_plane), st.plane_point, st.plane_normal, 0.0, 0.0)


def _at_rest(d: Drape) -> bool:
    """Update the rest test after a step: at rest = the garment's own motion over the last two steps
    (positions, not the solver's internal velocities, which the strain limits and contact planes keep
    resetting). Over two steps, because a point caught between the collision and its springs can flip
    between two places every step, going nowhere (three such points at the armpit of the DiffCloth dress on
    the large body, 2-3 cm a step, kept it from rest for 400 steps)."""
    st, s = d.state, d.settings
    dt = float(s.time_step)
    st.moves[1] = st.moves[0]
    np.subtract(st.x, st.x_step, out=st.moves[0])
    # x_step - moves[1]: where each point was two steps before (at the first step: where it started)
    st.energy = kinetic_energy_per_kg(st.x, st.x_step - st.moves[1], d.mass, 2 * dt if st.step > 1 else dt)
    st.x_step[:] = st.x
    if not np.isfinite(st.energy):
        raise FloatingPointError(f"simulation diverged at step {st.step}")
    if st.step > d.startup and st.step >= s.steps_of(s.min_steps) and st.energy < s.rest_energy:
        st.rest_run += 1
        if st.rest_run >= s.steps_of(s.rest_steps):
            st.rest_reached = True
    else:
        st.rest_run = 0
    return st.rest_reached
