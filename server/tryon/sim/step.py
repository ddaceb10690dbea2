"""One time step of a drape: the body's start-up change, Verlet, collision, the substeps' passes, the fast
projection of the strain limits if asked for, the guards.

See ``run.py``'s doc for the method. ``step(model, state, control)`` advances the state in place and tells
whether the garment has come to rest; it works from whatever state it is given (a fresh ``start`` or a drape that has
already run), so a caller may step a drape on for as long as it likes.
"""

from __future__ import annotations

import numpy as np

from tryon.sim.blocks import block_order
from tryon.sim.collision.collider import BodyCollider
from tryon.sim.collision.contacts import (
    points_to_test, project_listed, reuse_planes, take_stricter_planes,
)
from tryon.sim.collision.self_contact import keep_drape_sides
from tryon.sim.collision.untangle import untangle
from tryon.sim.constraints import (
    cap_stretch, contact_springs, folded_at, pack_sweep, solve_listed, sweep_springs, top_down_order,
)
from tryon.sim.integrate import kinetic_energy_per_kg, verlet_step
from tryon.sim.pieces import hanging_pieces
from tryon.sim.projection import project_stretch, sticking
from tryon.sim.state import BodyControl, Drape, DrapeModel, DrapeState
from tryon.sim.substeps import Planes, Springs, Substeps, Sweep, finish_step


def step(model: DrapeModel, state: DrapeState, control: BodyControl) -> bool:
    """Advance ``state`` by one time step of ``model`` on the body as ``control`` has it at that step (grown,
    the arms turned, moved); True once the garment is at rest: its motion over (``settings.rest_energy``, after the
    start-up and ``settings.min_steps``) and then, settled under heavy drag, its forces balanced (``_at_rest``).
    Reads ``model``; writes ``state`` and the control's collider (its schedule applied). Raises FloatingPointError
    if the simulation diverged."""
    s, st, tu = model.settings, state, model.tuning
    x, x_prev, inv_mass = st.x, st.x_prev, st.inv_mass
    st.step += 1
    n = st.step
    changing = n <= control.startup
    _body_at(control, st, n, s.grow_from)
    # no gravity while the body grows / the arms turn back: the garment must not slide off a body that is
    # not yet its full size (the fit phase); it falls once the body is complete
    gravity = 0.0 if changing else s.gravity
    mu_s, mu_k = s.friction_static, s.friction_kinetic
    # the first substep's prediction, collision and passes here; its tail and the other substeps in one
    # kernel (``finish_step``)
    drag = tu.settle_drag if st.settling else s.air_drag
    verlet_step(x, x_prev, inv_mass, model.h, gravity, drag, s.max_speed)
    # a re-posed drape does not leave a pinched point deeper in the body than the collision's reach within a
    # step (``collide_points``' hold_depth); a drape from scratch holds it wherever it is
    hold_depth = model.reach if control.moving else 1e9
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
    st.collided = control.collider.collide(x, x_prev, inv_mass, st.active, control.parts, s.contact_offset, mu_s,
                                           mu_k, st.contact, near=tu.near, planes=st.planes,
                                           hold_pinched=not changing, held=st.held, hold_depth=hold_depth,
                                           two=model.two_threads)
    st.x_checked[st.active] = x[st.active]
    if st.layer_has.any():
        take_stricter_planes(x, *st.planes, *st.layer_planes)
    touching = np.flatnonzero(st.has_plane)  # the points with a contact plane this step
    # points on the body count as heavier in the springs, so hanging cloth hangs from them instead of
    # dragging them in (mass scaling)
    w_eff = np.where(st.has_plane, inv_mass * tu.contact_weight, inv_mass)
    contact_passes = tu.contact_passes if not changing else 0
    if contact_passes:
        st.body_ends, st.body_table, st.body_blocks = contact_springs(model.ends, st.table, st.has_plane,
                                                                      model.blocks)
    solve_listed(x, x_prev, w_eff, model.ends, st.table, model.per_sub, touching, st.plane_point,
                 st.plane_normal, 0.0, 0.0, st.push, 1.0, model.blocks)
    if contact_passes:
        solve_listed(x, x_prev, w_eff, st.body_ends, st.body_table, contact_passes, touching, st.plane_point,
                     st.plane_normal, 0.0, 0.0, st.push, 1.0, st.body_blocks)
    _sweep_springs(model, st, refresh=n % tu.order_refresh == 1, hanging=not changing)
    planes = Planes(touching, st.plane_point, st.plane_normal, st.has_plane, st.push)
    # the top-down sweep is for cloth hanging under gravity; without gravity (growth) its upward bias would
    # make a tight garment climb off the body (sweep: not changing)
    run = Substeps(float(model.h), int(model.n_sub), int(model.per_sub), int(contact_passes), float(gravity),
                   float(drag), float(s.max_speed), float(mu_s), float(mu_k), not changing,
                   bool(tu.sweep_every_substep), float(model.floor_y))
    movers = control.collider.movers(st, control.parts, s.contact_offset, tu.near, model.reach,
                                     hold_pinched=not changing, retest_planes=control.moving, hold_depth=hold_depth,
                                     two=model.two_threads)
    finish_step(x, x_prev, inv_mass, w_eff, Springs(model.ends, st.table, model.blocks),
                Springs(st.body_ends, st.body_table, st.body_blocks),
                Sweep(st.sweep_ends, st.sweep_lmax, st.sweep_blocks), planes, run, movers)
    if s.projection_steps and not changing:
        _project(model, st, w_eff)
    if tu.self_thickness:
        keep_drape_sides(model, st, st.x_step, np.where(st.held, 0.0, w_eff))
    # not while the body changes: the start-up's arms' turn carries sleeves through the torso's cloth on purpose
    # (untangled then, the hanging-sleeve long-sleeve's cuffs ended round the upper arms), a re-pose's motion
    # crushes cloth in a bending elbow's crook
    if tu.untangle_step and tu.untangle_every and n % tu.untangle_every == 0 and not (changing or control.moving):
        untangle(model, st)
    if not changing or control.moving:  # a re-pose's start-up is the body's motion, shown: its frames too
        _out_of_the_body(model, st, control)
    # guard: collision wins over the springs within the step, so a garment far too small for its body (a
    # size S shirt on the largest body) would be stretched without bound; past ``tear_guard`` x its natural
    # length a spring wins instead (the point may stay inside the body: the metrics report it). In a normal
    # drape only a few short springs reach it for a few steps (of the catalogue's M garments on the three
    # bodies: the long-sleeve M's cuffs round the hands on the medium body, the trousers M's hem caught under a
    # sole there), and a re-pose's straddled limbs.
    cap_stretch(x, inv_mass, model.springs, model.rest, tu.tear_guard, tu.tear_passes)
    if len(st.folded):
        _unfold(model, st)
    return _at_rest(model, st, control.startup)


def step_drape(d: Drape) -> bool:
    """``step`` on a drape's three parts (its model, state and control)."""
    return step(d.model, d.state, d.control)


def _body_at(control: BodyControl, st: DrapeState, n: int, grow_from: float) -> None:
    """The control's schedule at step ``n``: the body grown (from ``grow_from`` of its radius to full size over
    ``control.grow_steps`` steps), the arms turned (carrying the garment's points in ``st`` with them), the
    start's pinned points freed."""
    turning = bool(control.arms.steps) and n <= control.arms.steps + 1
    if control.grow_steps and n <= control.grow_steps + 1:
        scale = grow_from + (1.0 - grow_from) * min(1.0, n / control.grow_steps)
        control.collider.set_scale(scale, refresh=not turning)  # the arms' turn recomputes the surface anyway
    if turning:
        control.arms.apply(n)
        control.arms.carry(st.x, st.x_prev)
    if control.pinned_until and n == control.pinned_until:
        st.inv_mass[:] = control.saved_inv_mass


def _sweep_springs(model: DrapeModel, st: DrapeState, refresh: bool, hanging: bool) -> None:
    """The top-down sweep's springs in ``st``: every spring from the top down (``refresh``: ordered again from
    where the points are now), and of those the hanging ones (``hanging``: the body is complete)."""
    if refresh:
        order, st.ordered_blocks = block_order(top_down_order(st.x, model.springs), model.blocks)
        st.ordered_ends, st.ordered_lmax = pack_sweep(model.ends, st.table, order)
    if hanging:
        hangs = hanging_pieces(model.piece, st.has_plane | (st.inv_mass == 0.0))
        st.sweep_ends, st.sweep_lmax, st.sweep_blocks = sweep_springs(st.ordered_ends, st.ordered_lmax,
                                                                      st.has_plane, hangs, st.ordered_blocks)


def _out_of_the_body(model: DrapeModel, st: DrapeState, control: BodyControl) -> None:
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
    collider, parts, tu = control.collider, control.parts, model.tuning
    if len(parts) < 2:
        return
    _held_back(st, collider, parts, tu.frame_depth)
    touching = np.flatnonzero(st.has_plane & ~st.held)
    deep = touching[collider.depth(st.x[touching], parts, two=model.two_threads) > tu.frame_depth]
    if len(deep) == 0:
        return
    st.active[:] = False
    st.active[deep] = True
    collider.collide(st.x, st.x_prev, st.inv_mass, st.active, parts, model.settings.contact_offset, 0.0, 0.0,
                     st.contact, near=tu.near, planes=st.planes, held=np.zeros(len(st.x), dtype=np.bool_),
                     hold_depth=model.reach)
    st.x_checked[deep] = st.x[deep]


def _held_back(st: DrapeState, collider: BodyCollider, parts: np.ndarray, frame_depth: float) -> None:
    """Every point held in a pinch between two parts (``collide_points``' ``hold_pinched``: pushed out of each it
    would flip between them) that the step's springs drew more than ``frame_depth`` m into the body (the
    ``collider``'s ``parts``), deeper
    than where it began the step, goes back there, at rest. The pinch holds it where the step began, but within
    the substeps its springs still move it: a crotch point of the small body's trousers XL, between the thighs,
    was drawn 10.3 mm into the right one in a shown frame (``tryon bench --only fit``: 4 of the 90 drapes showed
    such a frame: the small body's trousers M, XL, XXL and the medium body's XXL)."""
    held = np.flatnonzero(st.held)
    if len(held) == 0:
        return
    now = collider.depth(st.x[held], parts)
    deep = now > frame_depth
    if not deep.any():
        return
    drawn = held[deep]
    back = drawn[collider.depth(st.x_step[drawn], parts) < now[deep]]
    st.x[back] = st.x_step[back]
    st.x_prev[back] = st.x_step[back]


def _unfold(model: DrapeModel, st: DrapeState) -> None:
    """The folded springs (``st.folded``) drawn back to their natural length (within ``tuning.folded_below``)
    resist compression again (``st.table`` gets back their packed compression) and are no longer folded."""
    folded = st.folded
    back = ~folded_at(st.x, model.springs[folded], model.rest[folded], model.tuning.folded_below)
    st.table[folded[back], 2] = model.table[folded[back], 2]
    st.folded = folded[~back]


def _project(model: DrapeModel, st: DrapeState, w_eff: np.ndarray) -> None:
    """The step's fast projection of the strain limits (``projection.py``), ``settings.projection_steps``
    Newton steps, with the passes' weights ``w_eff`` (k,) 1/kg; positions only (x_prev moves with x), then
    the contact planes again."""
    w = np.empty_like(w_eff)
    sticking(st.x, st.x_step, w_eff, st.has_plane, st.plane_normal, w)
    before = st.x.copy()
    project_stretch(st.x, w, model.ends, st.table, st.has_plane, st.plane_normal, model.settings.projection_steps,
                    model.blocks)
    st.x_prev += st.x - before
    project_listed(st.x, st.x_prev, np.flatnonzero(st.has_plane), st.plane_point, st.plane_normal, 0.0, 0.0)


def _at_rest(model: DrapeModel, st: DrapeState, startup: int) -> bool:
    """Update the rest test after a step; True once the garment has come to rest. Two phases, both on the points'
    own motion over the last two steps (positions, not the solver's internal velocities, which the strain limits
    and contact planes keep resetting; over two steps, because a point caught between the collision and its
    springs can flip between two places every step, going nowhere: three such points at the armpit of the DiffCloth
    dress on the large body, 2-3 cm a step, kept it from rest for 400 steps):
    - the motion: until the mean kinetic energy per kilogram is under ``settings.rest_energy`` (not within the
      body's ``startup`` steps nor before ``settings.min_steps``); then the settle begins (``st.settling``: the
      steps' drag is ``tuning.settle_drag``);
    - the settle: until the 99th percentiles of the points' speed and of the force on them not balanced
      (``_balance``) are under ``settings.rest_speed`` and ``settings.rest_force``, or no longer come down
      (``tuning.stall_rounds``, ``stall_progress``): then it ends unbalanced."""
    s = model.settings
    dt = float(s.time_step)
    st.moves[1:] = st.moves[:-1]
    np.subtract(st.x, st.x_step, out=st.moves[0])
    # x_step - moves[1]: where each point was two steps before (at the first step: where it started)
    st.energy = kinetic_energy_per_kg(st.x, st.x_step - st.moves[1], model.mass, 2 * dt if st.step > 1 else dt)
    st.x_step[:] = st.x
    if not np.isfinite(st.energy):
        raise FloatingPointError(f"simulation diverged at step {st.step}")
    if not st.settling and st.step > startup and st.step >= s.steps_of(s.min_steps) and st.energy < s.rest_energy:
        st.settling = True
    elif st.settling and st.step >= 4:
        tu = model.tuning
        st.speed, st.force = _balance(st.moves, dt, tu.settle_drag, BALANCE_SHARE)
        st.balanced = st.speed < s.rest_speed and st.force < s.rest_force
        off = max(st.speed / s.rest_speed, st.force / s.rest_force)
        if off <= tu.stall_progress * st.settle_best:
            st.settle_best, st.settle_best_at = off, st.step
        stalled = st.step - st.settle_best_at >= s.steps_of(tu.stall_rounds)
        st.rest_reached |= st.balanced or stalled
    return st.rest_reached


# The share of a drape's points whose motion and balance its rest test reads (``_at_rest``): all but the odd
# point the collision and its springs hold in a cycle (one of two steps is balanced on average).
BALANCE_SHARE = 0.99


def _balance(moves: np.ndarray, dt: float, drag: float, share: float) -> tuple[float, float]:
    """(speed m/s, force N/kg): the ``share`` quantiles over the points of their speed over the last two steps
    and of the force on them that is not balanced, from their moves (4, k, 3) m in the last four steps (the last
    first), ``dt`` s each, under air ``drag`` 1/s. The force per kilogram is the two-step acceleration plus what
    the drag takes (a = f - drag v): a point creeping at a drag-limited speed is not balanced."""
    recent = moves[0] + moves[1]
    before = moves[2] + moves[3]
    velocity = recent / (2.0 * dt)
    force = (recent - before) / (2.0 * dt) ** 2 + drag * velocity
    speed = np.sqrt(np.einsum("ij,ij->i", velocity, velocity))
    unbalanced = np.sqrt(np.einsum("ij,ij->i", force, force))
    return float(np.quantile(speed, share)), float(np.quantile(unbalanced, share))
