"""The substeps of one simulation step in a single kernel (the loop's inner part, ``run.py``).

A step is ``n_sub`` substeps of about eight kernel calls each; called one by one from Python (~2 us of
dispatch each with their ten-odd arguments, plus the Python between them) they cost ~0.35 ms per step on
the perf T-shirt (16 substeps, ``python3 -m tryon.bench.perf``: loop CPU 8.1 -> 7.7 ms per step on a loaded
machine). Here the substeps run in one call; what needs Python (the collision, the order refresh,
growth, the rest test) stays once per step in ``run.drape``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from tryon.sim.blocks import sweep_blocked
from tryon.sim.collision.contacts import friction_split, project_listed, project_split
from tryon.sim.collision.movers import collide_movers
from tryon.sim.constraints import solve_listed
from tryon.sim.integrate import keep_above_floor, verlet_split, verlet_step


class Springs(NamedTuple):
    """Springs as a pass reads them: ends (s, 2) uint32 and table (s, 5) (``constraints.pack_springs``), in the
    blocks (3,) int64 of ``constraints._blocked_pass``. The garment's springs, or those of them a step selects (the
    contact passes' springs with both ends on the body)."""

    ends: np.ndarray
    table: np.ndarray
    blocks: np.ndarray


class Sweep(NamedTuple):
    """The top-down sweep's springs (``constraints.sweep_springs``): ends (q, 2) uint32, lmax (q,) m, blocks (3,)
    int64 (``blocks.sweep_blocked``)."""

    ends: np.ndarray
    lmax: np.ndarray
    blocks: np.ndarray


class Planes(NamedTuple):
    """The step's contact planes, from its collision: touching (q,) int64 the points with a plane (increasing),
    point (k, 3) m and normal (k, 3) unit each point's plane, has (k,) bool; push (k,) m the pushes summed over a
    substep for friction (written; zero after each substep)."""

    touching: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    has: np.ndarray
    push: np.ndarray


class Substeps(NamedTuple):
    """How a step's substeps run: n_sub substeps of h s, per_sub passes over the springs and contact_passes over
    those on the body in each; gravity m/s^2, air_drag 1/s, max_speed m/s (``verlet_step``); mu_static,
    mu_kinetic: Coulomb friction on the planes; sweep: the top-down sweep on (after every substep if
    sweep_every_substep, else after the last); floor_y m."""

    h: float
    n_sub: int
    per_sub: int
    contact_passes: int
    gravity: float
    air_drag: float
    max_speed: float
    mu_static: float
    mu_kinetic: float
    sweep: bool
    sweep_every_substep: bool
    floor_y: float


@njit(cache=True, nogil=True)
def finish_step(x, x_prev, inv_mass, w_eff, springs, on_body, sweep, planes, run, movers):
    """The rest of a step whose first substep has been predicted, collided and passed over (the caller's
    part: ``verlet_step``, the collision, then ``solve_listed`` over ``springs`` and, if ``run.contact_passes``,
    over ``on_body``), in place.

    Reads: inv_mass (k,) 1/kg, w_eff (k,) 1/kg (the passes' weights), springs and on_body (``Springs``: the
    garment's, and those with both ends on the body), sweep (``Sweep``), run (``Substeps``). Writes: x, x_prev
    (k, 3) m, planes (``Planes``: push, and the planes the within-step test adds), movers (``collision.Movers``:
    the points without a plane that moved far since their collision test are tested again after each further
    substep's prediction, and join the planes if they get one).

    First substep: the top-down sweep (if on), the contact planes, friction, the floor. Each of the
    ``run.n_sub - 1`` further substeps: Verlet (eq. 1), the within-step test, the planes with friction on the
    inertial motion, ``run.per_sub`` passes over the springs and ``run.contact_passes`` over the body's springs,
    then the same tail. On a garment whose springs run in two blocks that may use two threads
    (``springs.blocks``), the prediction, the plane projections and friction run on two threads too, half the
    points each (``verlet_split``, ``project_split``, ``friction_split``): the same numbers.
    """
    touching = planes.touching
    two = springs.blocks[2] != 0
    for sub in range(run.n_sub):
        if sub > 0:
            verlet_split(x, x_prev, inv_mass, run.h, run.gravity, run.air_drag, run.max_speed, two)
            if collide_movers(x, x_prev, inv_mass, movers, run.mu_static, run.mu_kinetic, planes.has, planes.point,
                              planes.normal):
                touching = np.flatnonzero(planes.has)
            # friction acts on the inertial motion only (x - x_prev right after the prediction), never on
            # the springs' corrections (which stand for the cloth's tension)
            project_split(x, x_prev, touching, planes.point, planes.normal, run.mu_static, run.mu_kinetic, None, two)
            solve_listed(x, x_prev, w_eff, springs.ends, springs.table, run.per_sub, touching, planes.point,
                         planes.normal, 0.0, 0.0, planes.push, 1.0, springs.blocks)
            if run.contact_passes:
                solve_listed(x, x_prev, w_eff, on_body.ends, on_body.table, run.contact_passes, touching,
                             planes.point, planes.normal, 0.0, 0.0, planes.push, 1.0, on_body.blocks)
        if run.sweep and (sub == run.n_sub - 1 or run.sweep_every_substep):
            sweep_blocked(x, x_prev, w_eff, sweep.ends, sweep.lmax, planes.has, sweep.blocks)
        project_split(x, x_prev, touching, planes.point, planes.normal, 0.0, 0.0, planes.push, two)
        friction_split(x, x_prev, touching, planes.normal, planes.push, run.mu_static, run.mu_kinetic, two)
        keep_above_floor(x, x_prev, run.floor_y)


@njit(cache=True, nogil=True)
def finish_relaxation_round(x, x_prev, inv_mass, springs, planes, run):
    """The rest of a round of the relaxation after the loop (``run.drape``) whose first substep has been
    predicted and collided by the caller, in place: each substep's ``run.per_sub`` passes over ``springs``
    (``Springs``, stretch only) with the contact ``planes`` (``Planes``: their pushes written), the planes again, a
    frictionless floor at ``run.floor_y``; then the other ``run.n_sub - 1`` substeps, each with its Verlet
    prediction (no gravity, ``run.air_drag``) first. Writes x, x_prev (k, 3) m. One call instead of ~60 per round:
    the A-line skirt S on the large body (60 rounds) drapes in 0.274 instead of 0.278 s of CPU, same result.
    """
    for sub in range(run.n_sub):
        if sub > 0:
            verlet_step(x, x_prev, inv_mass, run.h, 0.0, run.air_drag, run.max_speed)
        solve_listed(x, x_prev, inv_mass, springs.ends, springs.table, run.per_sub, planes.touching, planes.point,
                     planes.normal, 0.0, 0.0, planes.push, 1.0, springs.blocks)
        project_listed(x, x_prev, planes.touching, planes.point, planes.normal, 0.0, 0.0)
        # a frictionless floor: a hem on it may still slide
        for i in range(x.shape[0]):
            if x[i, 1] < run.floor_y:
                x[i, 1] = run.floor_y
