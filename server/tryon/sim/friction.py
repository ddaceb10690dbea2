"""Coulomb friction on positions (Macklin et al. 2014, "Unified particle physics"): what the contact
projections, the friction after the passes and the collision response share."""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, nogil=True, fastmath=True, inline="always")
def coulomb_cut(mx, my, mz, nx, ny, nz, press, mu_static, mu_kinetic):
    """How much of a contact's tangential motion friction takes away.

    (mx, my, mz) m: the point's motion over the substep (x - x_prev); (nx, ny, nz): the contact's unit
    normal; press m: how far the body pushed the point out (>= 0). The tangential part t of the motion is
    cancelled if |t| <= mu_static x press (the point sticks), else shortened by mu_kinetic x press (it
    slides). Returns (cut, tx, ty, tz): the fraction of t to take away (0..1) and t (m)."""
    mn = mx * nx + my * ny + mz * nz
    tx = mx - mn * nx
    ty = my - mn * ny
    tz = mz - mn * nz
    tl = math.sqrt(tx * tx + ty * ty + tz * tz)
    if tl <= mu_static * press:
        return 1.0, tx, ty, tz
    return min(mu_kinetic * press / max(tl, 1e-15), 1.0), tx, ty, tz
