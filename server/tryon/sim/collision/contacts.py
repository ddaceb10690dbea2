"""Contacts: the planes a collision leaves, friction on them, which points to test again.

The body collision (``kernels.collide_points``) runs once per step; for every point it pushed out or found
within ``near`` of the body it leaves a contact plane (a point on the offset surface, the surface's unit
normal). The rest of the step keeps to those planes (``project_listed`` after every spring pass), with
Coulomb friction on positions (Macklin et al. 2014, "Unified particle physics": ``coulomb_cut``, shared by
every projection and the collision response). Next step a contact still near where it touched only
re-projects onto its plane (``reuse_planes``), and a point that has not moved since its last test and
touches nothing is not tested at all (``points_to_test``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


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


@njit(cache=True, nogil=True, fastmath=True)
def project_listed(x, x_prev, listed, plane_point, plane_normal, mu_static, mu_kinetic, push=None):
    """Keep the points ``listed`` (q,) int64 (those with a contact plane, increasing) on the outer side of
    their contact plane, in place: n . (x_i - q_i) >= 0 (q on the offset body surface + lambda, n its
    outward normal).

    A pushed point loses its normal velocity (x_prev moved along n: inelastic contact) and gets Coulomb
    friction on positions (Macklin et al. 2014): the tangential part of its motion since x_prev is
    cancelled if shorter than mu_static * d, else shortened by mu_kinetic * d (so garments stay on
    shoulders instead of creeping down them). ``push`` (k,), if given, accumulates each point's pushes (m)
    for ``apply_friction``.
    """
    for q in range(listed.shape[0]):
        i = listed[q]
        nx = plane_normal[i, 0]
        ny = plane_normal[i, 1]
        nz = plane_normal[i, 2]
        d = (x[i, 0] - plane_point[i, 0]) * nx + (x[i, 1] - plane_point[i, 1]) * ny + (x[i, 2] - plane_point[i, 2]) * nz
        if d >= 0.0:
            continue
        x[i, 0] -= d * nx
        x[i, 1] -= d * ny
        x[i, 2] -= d * nz
        if push is not None:
            push[i] -= d
        mx = x[i, 0] - x_prev[i, 0]
        my = x[i, 1] - x_prev[i, 1]
        mz = x[i, 2] - x_prev[i, 2]
        mn = mx * nx + my * ny + mz * nz
        # inelastic: the push must not become a velocity away from the body (no bounce)
        x_prev[i, 0] += mn * nx
        x_prev[i, 1] += mn * ny
        x_prev[i, 2] += mn * nz
        if mu_static <= 0.0:
            continue
        cut, tx, ty, tz = coulomb_cut(mx, my, mz, nx, ny, nz, -d, mu_static, mu_kinetic)
        x[i, 0] -= cut * tx
        x[i, 1] -= cut * ty
        x[i, 2] -= cut * tz


@njit(cache=True, nogil=True, fastmath=True)
def project_planes(x, x_prev, has_plane, plane_point, plane_normal, mu_static, mu_kinetic, push=None):
    """``project_listed`` for the points with ``has_plane`` (k,) bool."""
    project_listed(x, x_prev, np.flatnonzero(has_plane), plane_point, plane_normal, mu_static, mu_kinetic, push)


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def _project_halves(x, x_prev, listed, plane_point, plane_normal, mu_static, mu_kinetic, push):
    """``project_listed`` (same arguments) on two threads, the first half of ``listed`` on one, the rest on
    the other. No races: a point is listed once, and its projection reads and writes only its own rows of x,
    x_prev and push; the result is that of one call over all."""
    q = listed.shape[0]
    half = q // 2
    for t in prange(2):
        lo = 0 if t == 0 else half
        hi = half if t == 0 else q
        project_listed(x, x_prev, listed[lo:hi], plane_point, plane_normal, mu_static, mu_kinetic, push)


@njit(cache=True, nogil=True, fastmath=True)
def project_split(x, x_prev, listed, plane_point, plane_normal, mu_static, mu_kinetic, push, two):
    """``project_listed``, on two threads if ``two`` (a garment whose springs run in two blocks,
    ``blocks.split_springs``), else on the calling thread."""
    if two:
        _project_halves(x, x_prev, listed, plane_point, plane_normal, mu_static, mu_kinetic, push)
    else:
        project_listed(x, x_prev, listed, plane_point, plane_normal, mu_static, mu_kinetic, push)


@njit(cache=True, nogil=True, fastmath=True)
def apply_friction(x, x_prev, listed, plane_normal, push, mu_static, mu_kinetic):
    """Coulomb friction for the substep, in place, for the points ``listed`` (q,) int64 (those with a
    contact plane; the others are never pushed): a contact pushed out by ``push`` (k,) (m, summed over
    the passes: gravity and the cloth's own tension pressing it on the body, e.g. a waistband's hoop
    tension on the hips) keeps no tangential motion since x_prev if that motion is under mu_static x push
    (it sticks), else loses mu_kinetic x push of it (it slides). Then ``push`` is reset.

    This is what holds a skirt or trousers on the hips: the band's tension presses it on the slope, and
    the friction that pressure allows stops it sliding down.
    """
    for q in range(listed.shape[0]):
        i = listed[q]
        p = push[i]
        push[i] = 0.0
        if p <= 0.0:
            continue
        cut, tx, ty, tz = coulomb_cut(x[i, 0] - x_prev[i, 0], x[i, 1] - x_prev[i, 1], x[i, 2] - x_prev[i, 2],
                                      plane_normal[i, 0], plane_normal[i, 1], plane_normal[i, 2], p, mu_static,
                                      mu_kinetic)
        x[i, 0] -= cut * tx
        x[i, 1] -= cut * ty
        x[i, 2] -= cut * tz


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def _friction_halves(x, x_prev, listed, plane_normal, push, mu_static, mu_kinetic):
    """``apply_friction`` (same arguments) on two threads, half of ``listed`` each. No races: a point is listed
    once and its friction reads and writes only its own rows; the result is that of one call over all."""
    q = listed.shape[0]
    half = q // 2
    for t in prange(2):
        lo = 0 if t == 0 else half
        hi = half if t == 0 else q
        apply_friction(x, x_prev, listed[lo:hi], plane_normal, push, mu_static, mu_kinetic)


@njit(cache=True, nogil=True, fastmath=True)
def friction_split(x, x_prev, listed, plane_normal, push, mu_static, mu_kinetic, two):
    """``apply_friction``, on two threads if ``two`` (as ``project_split``)."""
    if two:
        _friction_halves(x, x_prev, listed, plane_normal, push, mu_static, mu_kinetic)
    else:
        apply_friction(x, x_prev, listed, plane_normal, push, mu_static, mu_kinetic)


@njit(cache=True, nogil=True)
def reuse_planes(x, x_prev, has_plane, plane_point, plane_normal, reuse, mu_static, mu_kinetic, contact, reused):
    """Contacts at rest cost almost nothing: a point with a contact plane from the last step that is still
    within ``reuse`` (m) of the plane's surface point is only projected onto that plane (with friction,
    see ``project_planes``) instead of being queried against the maps again; ``reused`` (k,)
    bool out marks them, ``contact`` (k,) whether they were pushed. Returns how many were reused.

    The plane is the body's tangent plane where the point last touched it; within 1 cm on a 5 cm arm it
    lies at most 1 mm off the surface, a quarter of the collision margin.
    """
    n = 0
    for i in range(x.shape[0]):
        reused[i] = False
        if not has_plane[i]:
            continue
        dx = x[i, 0] - plane_point[i, 0]
        dy = x[i, 1] - plane_point[i, 1]
        dz = x[i, 2] - plane_point[i, 2]
        if dx * dx + dy * dy + dz * dz > reuse * reuse:
            continue
        reused[i] = True
        n += 1
        nx = plane_normal[i, 0]
        ny = plane_normal[i, 1]
        nz = plane_normal[i, 2]
        d = dx * nx + dy * ny + dz * nz
        contact[i] = d < 0.0
        if d >= 0.0:
            continue
        x[i, 0] -= d * nx
        x[i, 1] -= d * ny
        x[i, 2] -= d * nz
        cut, tx, ty, tz = coulomb_cut(x[i, 0] - x_prev[i, 0], x[i, 1] - x_prev[i, 1], x[i, 2] - x_prev[i, 2],
                                      nx, ny, nz, -d, mu_static, mu_kinetic)
        # friction on the tangential motion, and no velocity along the normal (inelastic)
        x[i, 0] -= cut * tx
        x[i, 1] -= cut * ty
        x[i, 2] -= cut * tz
        x_prev[i, 0] = x[i, 0] - (1.0 - cut) * tx
        x_prev[i, 1] = x[i, 1] - (1.0 - cut) * ty
        x_prev[i, 2] = x[i, 2] - (1.0 - cut) * tz
    return n


@njit(cache=True, nogil=True)
def points_to_test(x, x_checked, has_plane, reused, rest_move, active):
    """Which points the step's collision tests, into ``active`` (k,) bool: those that moved more than
    ``rest_move`` (m) since their last test (``x_checked`` (k, 3)) or have a contact plane, unless their
    plane was reused (``reused`` (k,) bool, see ``reuse_planes``). Returns how many."""
    n = 0
    for i in range(x.shape[0]):
        dx = x[i, 0] - x_checked[i, 0]
        dy = x[i, 1] - x_checked[i, 1]
        dz = x[i, 2] - x_checked[i, 2]
        active[i] = (dx * dx + dy * dy + dz * dz > rest_move * rest_move or has_plane[i]) and not reused[i]
        n += active[i]
    return n


@njit(cache=True, nogil=True, fastmath=True)
def take_stricter_planes(x, has_plane, plane_point, plane_normal, other_has, other_point, other_normal):
    """Where a point (x (k, 3) m) has a contact plane from another collider (``other_*``: a garment under it,
    ``layers.collide_layers``), keep of the two planes the one that asks more of it: the larger
    n . (q - x), how far the point must move along n to reach the plane's outer side. The other garment
    lies over the body, so over it that is its plane, and the step's substeps keep the point on the
    garment under it instead of on the body (where the next layer collision would push it out again: two
    layers of the same size fought like that every step and never came to rest). In place; returns how
    many planes were taken."""
    n = 0
    for i in range(x.shape[0]):
        if not other_has[i]:
            continue
        need_other = 0.0
        need_own = -np.inf
        for a in range(3):
            need_other += other_normal[i, a] * (other_point[i, a] - x[i, a])
        if has_plane[i]:
            need_own = 0.0
            for a in range(3):
                need_own += plane_normal[i, a] * (plane_point[i, a] - x[i, a])
        if need_other > need_own:
            has_plane[i] = True
            for a in range(3):
                plane_point[i, a] = other_point[i, a]
                plane_normal[i, a] = other_normal[i, a]
            n += 1
    return n
