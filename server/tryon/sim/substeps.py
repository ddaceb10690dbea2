"""The substeps of one simulation step in a single kernel (the loop's inner part, ``run.py``).

A step is ``n_sub`` substeps of about eight kernel calls each; called one by one from Python (~2 us of
dispatch each with their ten-odd arguments, plus the Python between them) they cost ~0.35 ms per step on
the perf T-shirt (16 substeps, ``python3 -m tryon.bench.perf``: loop CPU 8.1 -> 7.7 ms per step on a loaded
machine). Here the substeps run in one call; what needs Python (the collision, the order refresh,
growth, the rest test) stays once per step in ``run.drape``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from tryon.sim.blocks import sweep_blocked
from tryon.sim.collision.contacts import apply_friction, project_listed
from tryon.sim.collision.movers import collide_movers
from tryon.sim.constraints import ONE_BLOCK, solve_listed
from tryon.sim.integrate import keep_above_floor, verlet_step


@njit(cache=True, nogil=True)
def finish_step(x, x_prev, inv_mass, w_eff, h, gravity, air_drag, max_speed, n_sub, per_sub, ends, table,
                contact_passes, body_ends, body_table, touching, plane_point, plane_normal, has_plane, push,
                mu_static, mu_kinetic, sweep, sweep_every_substep, sweep_ends, sweep_lmax, floor_y, movers,
                blocks=ONE_BLOCK, body_blocks=ONE_BLOCK, sweep_blocks=ONE_BLOCK):
    """The rest of a step whose first substep has been predicted, collided and passed over (the caller's
    part: ``verlet_step``, the collision, then ``solve_listed`` over ``ends`` / ``table`` and, if
    ``contact_passes``, over ``body_ends`` / ``body_table``), in place.

    First substep: the top-down sweep (if ``sweep``), the contact planes, friction, the floor. Each of the
    ``n_sub - 1`` further substeps of ``h`` s: Verlet (eq. 1; inv_mass (k,)), the planes of the points
    ``touching`` (q,) int64 with friction on the inertial motion, ``per_sub`` passes over the springs and
    ``contact_passes`` over the body's springs (weighted by ``w_eff`` (k,)), then the same tail. The sweep
    runs on every substep if ``sweep_every_substep``, else on the last only. x, x_prev (k, 3) m;
    plane_point, plane_normal (k, 3) and has_plane (k,) bool from the collision; push (k,) the summed
    pushes for friction (zero on return); sweep_ends (q, 2) uint32 / sweep_lmax (q,) m from
    ``sweep_springs``; floor_y m; movers: the points without a plane that moved far since their collision test
    are tested again after each further substep's prediction (``collision.movers``), and join ``touching``
    if they get a plane. blocks, body_blocks, sweep_blocks (3,) int64: the blocks of ``ends``, ``body_ends``
    and ``sweep_ends`` (``constraints._blocked_pass``, ``sweep_blocked``).
    """
    for sub in range(n_sub):
        if sub > 0:
            verlet_step(x, x_prev, inv_mass, h, gravity, air_drag, max_speed)
            if collide_movers(x, x_prev, inv_mass, movers, mu_static, mu_kinetic, has_plane, plane_point,
                              plane_normal):
                touching = np.flatnonzero(has_plane)
            # friction acts on the inertial motion only (x - x_prev right after the prediction), never on
            # the springs' corrections (which stand for the cloth's tension)
            project_listed(x, x_prev, touching, plane_point, plane_normal, mu_static, mu_kinetic)
            solve_listed(x, x_prev, w_eff, ends, table, per_sub, touching, plane_point, plane_normal, 0.0, 0.0,
                         push, 1.0, blocks)
            if contact_passes:
                solve_listed(x, x_prev, w_eff, body_ends, body_table, contact_passes, touching, plane_point,
                             plane_normal, 0.0, 0.0, push, 1.0, body_blocks)
        if sweep and (sub == n_sub - 1 or sweep_every_substep):
            sweep_blocked(x, x_prev, w_eff, sweep_ends, sweep_lmax, has_plane, sweep_blocks)
        project_listed(x, x_prev, touching, plane_point, plane_normal, 0.0, 0.0, push)
        apply_friction(x, x_prev, touching, plane_normal, push, mu_static, mu_kinetic)
        keep_above_floor(x, x_prev, floor_y)


@njit(cache=True, nogil=True)
def finish_relaxation_round(x, x_prev, inv_mass, h, air_drag, max_speed, n_sub, per_sub, ends, table, touching,
                            plane_point, plane_normal, push, floor_y, blocks=ONE_BLOCK):
    """The rest of a round of the relaxation after the loop (``run.drape``) whose first substep has been
    predicted and collided by the caller, in place: each substep's ``per_sub`` passes over the springs
    ``ends`` / ``table`` (stretch only) with the contact planes of the points ``touching``, the planes again,
    a frictionless floor at ``floor_y`` m; then the other ``n_sub - 1`` substeps of ``h`` s, each with its
    Verlet prediction (no gravity, ``air_drag`` 1/s) first. One call instead of ~60 per round: the A-line
    skirt S on the large body (60 rounds) drapes in 0.274 instead of 0.278 s of CPU, same result.
    """
    for sub in range(n_sub):
        if sub > 0:
            verlet_step(x, x_prev, inv_mass, h, 0.0, air_drag, max_speed)
        solve_listed(x, x_prev, inv_mass, ends, table, per_sub, touching, plane_point, plane_normal, 0.0, 0.0, push,
                     1.0, blocks)
        project_listed(x, x_prev, touching, plane_point, plane_normal, 0.0, 0.0)
        # a frictionless floor: a hem on it may still slide
        for i in range(x.shape[0]):
            if x[i, 1] < floor_y:
                x[i, 1] = floor_y
