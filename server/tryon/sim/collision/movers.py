"""The body collision within a step, for the points that moved far since their test (``collide_movers``).

The step's collision (``kernels.collide_points``) runs on the first substep's prediction; every point it
pushed out or found near the body keeps a contact plane for the rest of the step. A point without a plane
that then moves more than the collision margin (cloth falling 4 cm a step onto a ball, a point the
springs pull towards the body from beyond ``near``) could enter the body before the next step's test:
``finish_step`` tests such points again after each substep's prediction, the same way, so a point is
never deeper in the real body than ``reach`` minus the margin. Points that moved less cost one distance
each; a garment at rest costs a scan.

In a re-posed drape (``retest_planes``: its whole settle, the body moving and after), points with a plane are
tested again too: a plane keeps a point off one part only, and where two parts meet (cloth squeezed between a
lowering arm and the torso) the springs pulled such a point, held off the arm, 2-4 cm into the torso within
the step. The M garments on the medium body through the ten poses of the motion stress's first sequence (seed
30): settles with a frame over 10 mm 16 -> 9 of 60 (T-shirt 2 -> 1, long-sleeve 8 -> 5, dress 3 -> 1, shorts
1 -> 0, trousers 2 -> 2), every check met 44 -> 50; with a pinched point put where it is least deep
(``collide_points``' hold_depth) 5 of 60 and 54. Not in a drape from scratch: there the planes hold cloth
the body supports (a waistband on the hips), and tested again mid-step it slid (the catalogue fit bench: 76 ->
74 garments staying up).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from tryon.sim.blocks import collide_halves
from tryon.sim.collision.kernels import BodySurface, collide_points


class Movers(NamedTuple):
    """What the within-step test reads and writes, as one argument of ``finish_step``.

    surface: the offset body (``BodySurface``); parts (q,) int64: the parts tested; x_checked (k, 3) m: where
    each point was last tested (updated); contact (k,) bool, held (k,) bool: the collision's outputs (see
    ``collide_points``); active (k,) bool: work space; reach m: a point without a plane that moved farther
    than this since its test is tested again; lam m: eq. 4's lambda; near m: planes for points this close;
    hold_pinched: hold points pinched between two parts (only while the body does not move); retest_planes:
    points with a plane are tested again too (a re-posed drape, see the module doc); hold_depth m: see
    ``collide_points``; two: half the points on each of two threads (``blocks.collide_halves``)."""

    surface: BodySurface
    parts: np.ndarray
    x_checked: np.ndarray
    contact: np.ndarray
    held: np.ndarray
    active: np.ndarray
    reach: float
    lam: float
    near: float
    hold_pinched: bool
    retest_planes: bool = False
    hold_depth: float = 1e9
    two: bool = False


@njit(cache=True, nogil=True)
def collide_movers(x, x_prev, inv_mass, movers, mu_static, mu_kinetic, has_plane, plane_point, plane_normal):
    """Test again the points without a contact plane that moved farther than ``movers.reach`` since their
    last test, in place (``collide_points``: pushed out with friction, a contact plane for those pushed or
    near). Returns how many got a plane (the caller's list of points with planes must then grow); with
    ``movers.retest_planes``, how many were tested (a point may also have lost its plane)."""
    reach2 = movers.reach * movers.reach
    x_checked, active = movers.x_checked, movers.active
    n = 0
    for i in range(x.shape[0]):
        active[i] = False
        if (has_plane[i] and not movers.retest_planes) or inv_mass[i] == 0.0:
            continue
        dx = x[i, 0] - x_checked[i, 0]
        dy = x[i, 1] - x_checked[i, 1]
        dz = x[i, 2] - x_checked[i, 2]
        if dx * dx + dy * dy + dz * dz > reach2:
            active[i] = True
            n += 1
    if n == 0:
        return 0
    if movers.two:
        collide_halves(x, x_prev, inv_mass, active, movers.parts, movers.surface, movers.lam, mu_static, mu_kinetic,
                       movers.contact, movers.near, has_plane, plane_point, plane_normal, movers.hold_pinched,
                       movers.held, movers.hold_depth)
    else:
        collide_points(x, x_prev, inv_mass, active, movers.parts, movers.surface, movers.lam, mu_static,
                       mu_kinetic, movers.contact, movers.near, has_plane, plane_point, plane_normal,
                       movers.hold_pinched, movers.held, movers.hold_depth)
    planes = 0
    for i in range(x.shape[0]):
        if active[i]:
            x_checked[i, 0] = x[i, 0]
            x_checked[i, 1] = x[i, 1]
            x_checked[i, 2] = x[i, 2]
            planes += has_plane[i]
    return n if movers.retest_planes else planes
