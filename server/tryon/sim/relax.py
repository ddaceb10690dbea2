"""The relaxation after the step loop: gravity and friction off, light drag, only over-long springs acting.

See ``run.py``'s doc for why. ``relax`` first makes the body whole (full size, arms in their real pose),
then runs rounds of one step's substeps each until every spring meets its strain target, progress stalls
or ``tuning.max_polish_rounds`` is reached; a piece of the file that the relaxation carried away (a garment
far too small for its body) goes back to where the loop left it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tryon.sim.collision.contacts import take_stricter_planes
from tryon.sim.collision.self_contact import keep_drape_sides
from tryon.sim.collision.untangle import untangle as untangle_drape
from tryon.sim.constraints import cap_stretch, spring_lengths
from tryon.sim.integrate import verlet_step
from tryon.sim.limbs import openings_on_limbs
from tryon.sim.metrics import allowed_length
from tryon.sim.state import Drape
from tryon.sim.substeps import Planes, Springs, Substeps, finish_relaxation_round


@dataclass
class Relaxation:
    """What ``relax`` did: rounds run; relax_move (k,) m, how far it moved each coarse point; piece_move
    (pieces,) m, each piece's ``tuning.relax_move_quantile`` of that; relaxed: whether every piece kept it."""

    rounds: int
    relax_move: np.ndarray
    piece_move: np.ndarray
    relaxed: bool


def complete_body(d: Drape) -> None:
    """The body at full size and in its real pose, the start's pins released (a loop stopped early)."""
    collider, arms, st = d.control.collider, d.control.arms, d.state
    if collider.scale != 1.0:
        collider.set_scale(1.0, refresh=not arms.steps)
    if arms.steps:
        arms.apply(arms.steps)
    if d.control.pinned_until and st.step < d.control.pinned_until:
        st.inv_mass[:] = d.control.saved_inv_mass


def relax(d: Drape) -> Relaxation:
    """Relax ``d``'s garment in place (see the module doc)."""
    complete_body(d)
    m, st = d.model, d.state
    tu = m.tuning
    x, x_prev, inv_mass = st.x, st.x_prev, st.inv_mass
    target = allowed_length(m.rest, m.limits[m.kind])
    rounds = 0
    x_prev[:] = x
    x_loop = x.copy()
    fewest_over, best_round = len(m.springs) + 1, 0
    springs, run = relaxation_passes(d)
    # the untangling while it makes progress, and in the first rounds only: where it cannot undo a crossing (cloth
    # pinched between two parts, on the floor) it fights the springs, and the rounds after it are theirs
    untangling, fewest_crossings, best_untangle = bool(tu.untangle_step and tu.untangle_every), np.inf, 0
    for rounds in range(1, tu.max_polish_rounds + 1):
        crossings = relaxation_round(d, springs, run, untangle=untangling)
        if untangling:
            if crossings < fewest_crossings:
                fewest_crossings, best_untangle = crossings, rounds
            untangling = (crossings > 0 and rounds - best_untangle < tu.min_polish_rounds
                          and rounds < tu.stall_rounds)
        if rounds >= tu.min_polish_rounds:
            # judged after the final collision the result gets (between two collision tests a point may
            # slide past its contact plane, over a sharp edge, and be pushed back out, stretching springs)
            collide_all(d)
            n_over = int(np.count_nonzero(spring_lengths(x, m.springs) > target))
            if n_over == 0:
                break
            if n_over <= tu.stall_progress * fewest_over:
                fewest_over, best_round = n_over, rounds
            elif rounds - best_round >= tu.stall_rounds:
                break  # no progress: a garment too small for the body there (its springs stay over)
    else:  # out of rounds: the last positions still get their final collision
        collide_all(d)
    relax_move = np.linalg.norm(x - x_loop, axis=1)
    # each piece of the file on its own (pieces meet only the body, never each other): an outfit's trousers
    # may be carried down the legs while its shirt barely moves
    piece_move = np.array([np.quantile(relax_move[m.piece == p], tu.relax_move_quantile)
                           for p in range(int(m.piece.max()) + 1)])
    carried = piece_move > tu.relax_max_move
    # nor may it take a sleeve or trouser leg off its limb (a T-shirt on arms hanging against the torso: the
    # sleeves, pinched between arm and torso, pulled up off the arms)
    body = d.control.body
    for (_, _, loop), before, after in zip(m.openings, openings_on_limbs(x_loop, body, m.openings),
                                           openings_on_limbs(x, body, m.openings)):
        if before["ok"] and not after["ok"]:
            carried[m.piece[loop[0]]] = True
    relaxed = not carried.any()
    if not relaxed:
        # the relaxation carried a piece away: that piece stays where the loop left it, its springs over the
        # target reported as they are
        back = carried[m.piece]
        x[back] = x_loop[back]
        x_prev[:] = x
        collide_all(d)
    # the tear guard again: the final collision wins over the springs, so a garment far too small for its
    # body would leave it with springs pushed past the guard (the loop's guard ran before it)
    cap_stretch(x, inv_mass, m.springs, m.rest, tu.tear_guard, tu.tear_passes)
    return Relaxation(rounds=rounds, relax_move=relax_move, piece_move=piece_move, relaxed=relaxed)


def relaxation_passes(d: Drape) -> tuple[Springs, Substeps]:
    """The springs and substeps of a relaxation round of ``d``: only the over-long springs act (no compression
    pushes cloth off the body; with l0 = 0 too a compressed spring is not even visited, so the passes skip the
    buckled cloth on the body); gravity and friction off, the settle's drag (``tuning.settle_drag``)."""
    m = d.model
    stretch_only = m.table.copy()
    stretch_only[:, 1:] = 0.0
    run = Substeps(float(m.h), int(m.n_sub), int(m.per_sub), 0, 0.0, float(m.tuning.settle_drag),
                   float(m.settings.max_speed), 0.0, 0.0, False, False, float(m.floor_y))
    return Springs(m.ends, stretch_only, m.blocks), run


def relaxation_round(d: Drape, springs: Springs, run: Substeps, untangle: bool = False) -> int:
    """One round of the relaxation of ``d`` in place (``springs``, ``run``: ``relaxation_passes``): the first
    substep's prediction and collision here (every point tested, a pinched one held; a point an outfit's layer
    collision pushed keeps that layer's plane where it asks more, as in ``step``), the rest of the round in one
    kernel, a round of the untangling if ``untangle`` (``collision/untangle.py``), then the tear guard. Returns the
    crossings that round found (-1: none looked for)."""
    m, st, control = d.model, d.state, d.control
    s, tu = m.settings, m.tuning
    x, x_prev, inv_mass = st.x, st.x_prev, st.inv_mass
    x_start = x.copy() if tu.self_thickness else x
    verlet_step(x, x_prev, inv_mass, m.h, 0.0, tu.settle_drag, s.max_speed)
    st.active[:] = True
    # a point pinched between two parts (pushed out of each into the other) does not flip between them: it is
    # held where the round began or, if that is deeper than the collision's reach, put where the pushes leave
    # it least deep (as a re-posed drape's steps do; the body is whole here, nothing grows into it). Flipping
    # between the thighs, the legs of trousers on a larger body crossed each other
    control.collider.collide(x, x_prev, inv_mass, st.active, control.parts, s.contact_offset, 0.0, 0.0, st.contact,
                             near=tu.near, planes=st.planes, hold_pinched=True, held=st.held,
                             hold_depth=m.reach, two=m.two_threads)
    if st.layer_has.any():
        take_stricter_planes(x, *st.planes, *st.layer_planes)
    touching = np.flatnonzero(st.has_plane)
    finish_relaxation_round(x, x_prev, inv_mass, springs, Planes(touching, st.plane_point, st.plane_normal,
                                                                  st.has_plane, st.push), run)
    if tu.self_thickness:
        w = np.where(st.held, 0.0, np.where(st.has_plane, inv_mass * tu.contact_weight, inv_mass))
        keep_drape_sides(m, st, x_start, w)
    crossings = untangle_drape(m, st) if untangle and tu.untangle_step else -1
    cap_stretch(x, inv_mass, m.springs, m.rest, tu.tear_guard, tu.tear_passes)
    return crossings


def collide_all(d: Drape) -> None:
    """Every point out of the body, without friction (the relaxation's and the result's final collision)."""
    st = d.state
    st.active[:] = True
    d.control.collider.collide(st.x, st.x_prev, st.inv_mass, st.active, d.control.parts,
                               d.model.settings.contact_offset, 0.0, 0.0, st.contact, two=d.model.two_threads)
