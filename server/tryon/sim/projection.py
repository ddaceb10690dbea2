"""Fast projection of the strain limits (Goldenthal et al. 2007, "Efficient simulation of inextensible
cloth"): the springs past their limit brought back together, by a few Newton steps on the whole set.

The substeps' Gauss-Seidel passes carry a correction one spring further per pass, so a sheet whose tension
runs over many springs stays past its limits (issue 26: the 4k cloth on the ball at 0.47 over all frames with
16 passes a step; 217 passes to converge from one of its states). Here the springs over their limit,
C_a = |x_i - x_j| - l_max,a > 0, are solved together. Each Newton step linearises them,

    (J W J^T + r D) lambda = C,    dx = -W J^T lambda,

J the constraints' gradient (a row per spring: +n_a at i, -n_a at j, n_a its unit direction), W the points'
inverse masses, D the system's diagonal and r = REGULARISE, and solves the sparse system by conjugate
gradients (Jacobi-preconditioned), which carry a correction across many springs in one solve. The r D term
damps the step (Levenberg-Marquardt): the springs are redundant (structural, shear and bending springs over the
same points) and a flat sheet can shorten them by buckling, so the undamped step goes far out of the sheet. A
step that leaves the largest excess larger is halved (at most MAX_HALVINGS times, then undone), so the
projection never makes the worst spring worse; far past the limits (a sheet stretched 25 %) it then stops
where it started.

- A point on a contact plane moves along its plane only (W_i = w_i (I - n n^T)): the projection neither
  pulls it into the body nor lifts it off. A point that sticks (moved less than ``STICK_MOVE`` along its
  plane over the step, ``sticking``) does not move at all: static friction holds it, and a waistband held up
  by friction on the hips must not slide down because its springs are shortened.
- A spring neither of whose ends can move along it is left to the body (``too_tight`` reports it).
- The projection changes positions, not velocities (the caller moves x_prev with x): its work is to undo
  the stretch that the passes left, not to throw the cloth.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from tryon.sim.constraints import ONE_BLOCK

# Relative slack of the active set: a spring joins when longer than l_max (1 + ACTIVE_SLACK), so one left at
# its limit by rounding is not solved again.
ACTIVE_SLACK = 1e-3
# Relative regularisation r of the system's diagonal (the damping above). On the ball's 4k cloth (max stretch
# over all frames, 4 Newton steps): r = 1e-4 blew up, 0.01 left 0.51 (worse than without the projection),
# 0.05 0.19, 0.1 0.16, 0.3 0.17. A damped step takes back only part of a long-range excess: a pinned chain of
# nine springs 9 % past its limits loses ~1 % of it per step, where the undamped step meets it at once.
REGULARISE = 0.1
# Conjugate-gradient iterations per Newton step at most (they stop at a 1e-3 relative residual first); 25
# with 4 Newton steps: the 4k ball cloth at 0.159 over all frames, as good as 8 x 50 (0.137-0.152) within
# the runs' spread, at about half the cost.
CG_STEPS = 25
# A spring counts as met within 1 % of its limit (the bound): Newton steps stop when every movable
# spring is within it.
TOLERANCE = 0.01
# A Newton step that leaves the largest relative excess larger is halved, at most this many times, then undone.
MAX_HALVINGS = 4
# m: a contact point that moved less than this along its plane over a step sticks (a 0.02 s step: 2.5 cm/s).
STICK_MOVE = 0.0005


@njit(cache=True, nogil=True, fastmath=True, inline="always")
def _w_times(w, free_along, plane_normal, i, vx, vy, vz):
    """W_i v: the inverse mass times v, along the point's contact plane only if ``free_along[i]``."""
    wi = w[i]
    if free_along[i]:
        nx = plane_normal[i, 0]
        ny = plane_normal[i, 1]
        nz = plane_normal[i, 2]
        vn = vx * nx + vy * ny + vz * nz
        return wi * (vx - vn * nx), wi * (vy - vn * ny), wi * (vz - vn * nz)
    return wi * vx, wi * vy, wi * vz


@njit(cache=True, nogil=True, fastmath=True)
def _spread(m, act, ends, dirs, lam, acc):
    """acc += J^T lam over the m active springs (acc (k, 3), zero where no active spring ends)."""
    for a in range(m):
        s = act[a]
        i = ends[s, 0]
        j = ends[s, 1]
        for c in range(3):
            acc[i, c] += lam[a] * dirs[a, c]
            acc[j, c] -= lam[a] * dirs[a, c]


@njit(cache=True, nogil=True, fastmath=True)
def _apply(m, act, ends, dirs, w, free_along, plane_normal, diag, p, acc, out):
    """out = (J W J^T + REGULARISE D) p over the m active springs; acc (k, 3) scratch, zero on entry and
    return."""
    _spread(m, act, ends, dirs, p, acc)
    for a in range(m):
        s = act[a]
        i = ends[s, 0]
        j = ends[s, 1]
        ax, ay, az = _w_times(w, free_along, plane_normal, i, acc[i, 0], acc[i, 1], acc[i, 2])
        bx, by, bz = _w_times(w, free_along, plane_normal, j, acc[j, 0], acc[j, 1], acc[j, 2])
        out[a] = dirs[a, 0] * (ax - bx) + dirs[a, 1] * (ay - by) + dirs[a, 2] * (az - bz) + REGULARISE * diag[a] * p[a]
    for a in range(m):
        s = act[a]
        for c in range(3):
            acc[ends[s, 0], c] = 0.0
            acc[ends[s, 1], c] = 0.0


@njit(cache=True, nogil=True, fastmath=True)
def _active_range(x, w, ends, table, free_along, plane_normal, lo, hi, act, dirs, c, diag, at):
    """Fill the active set of the springs [lo, hi) (those over l_max (1 + ACTIVE_SLACK) that can move along
    their length) from entry ``at`` on: their indices, unit directions (i - j), violations (m) and system
    diagonals. Returns (the entry after the last filled, how many of them are past l_max (1 + TOLERANCE))."""
    m = at
    left = 0
    for s in range(lo, hi):
        i = ends[s, 0]
        j = ends[s, 1]
        dx = x[i, 0] - x[j, 0]
        dy = x[i, 1] - x[j, 1]
        dz = x[i, 2] - x[j, 2]
        d2 = dx * dx + dy * dy + dz * dz
        lmax = table[s, 0]
        if d2 <= lmax * lmax * (1.0 + ACTIVE_SLACK) ** 2:
            continue
        d = math.sqrt(d2)
        nx = dx / d
        ny = dy / d
        nz = dz / d
        ax, ay, az = _w_times(w, free_along, plane_normal, i, nx, ny, nz)
        bx, by, bz = _w_times(w, free_along, plane_normal, j, nx, ny, nz)
        dg = nx * (ax + bx) + ny * (ay + by) + nz * (az + bz)
        if dg <= 1e-12 * (w[i] + w[j] + 1e-30):
            continue  # neither end can move along the spring: the body holds it
        if d > lmax * (1.0 + TOLERANCE):
            left += 1
        act[m] = s
        dirs[m, 0] = nx
        dirs[m, 1] = ny
        dirs[m, 2] = nz
        c[m] = d - lmax
        diag[m] = dg
        m += 1
    return m, left


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def _active_halves(x, w, ends, table, free_along, plane_normal, blocks, act, dirs, c, diag):
    """``_active`` over springs in two blocks (``blocks.split_springs``: [A | B | boundary], ``blocks`` (3,)
    int64): A's and B's active springs found on two threads, B's then moved up behind A's, then the
    boundary's. No races: each thread reads the positions only and writes the entries of its own block's
    range of act, dirs, c and diag; the set, in order, is that of one scan over all."""
    na = blocks[0]
    m_ab = na + blocks[1]
    end = np.zeros(2, dtype=np.int64)
    left = np.zeros(2, dtype=np.int64)
    for t in prange(2):
        lo = 0 if t == 0 else na
        hi = na if t == 0 else m_ab
        end[t], left[t] = _active_range(x, w, ends, table, free_along, plane_normal, lo, hi, act, dirs, c, diag,
                                        lo)
    m = end[0]
    for a in range(na, end[1]):
        act[m] = act[a]
        dirs[m, 0] = dirs[a, 0]
        dirs[m, 1] = dirs[a, 1]
        dirs[m, 2] = dirs[a, 2]
        c[m] = c[a]
        diag[m] = diag[a]
        m += 1
    m, last = _active_range(x, w, ends, table, free_along, plane_normal, m_ab, ends.shape[0], act, dirs, c, diag,
                            m)
    return m, left[0] + left[1] + last


@njit(cache=True, nogil=True, fastmath=True)
def _active(x, w, ends, table, free_along, plane_normal, act, dirs, c, diag, blocks):
    """Fill the active set (springs over l_max (1 + ACTIVE_SLACK) that can move along their length): their
    indices, unit directions (i - j), violations (m) and system diagonals; on two threads where ``blocks``
    allows (``_active_halves``). Returns (how many, how many of them are past l_max (1 + TOLERANCE))."""
    if blocks[2]:
        return _active_halves(x, w, ends, table, free_along, plane_normal, blocks, act, dirs, c, diag)
    return _active_range(x, w, ends, table, free_along, plane_normal, 0, ends.shape[0], act, dirs, c, diag, 0)


@njit(cache=True, nogil=True, fastmath=True)
def project_stretch(x, w, ends, table, free_along, plane_normal, newton_steps, blocks=ONE_BLOCK):
    """Bring the springs over their limits back towards them, in place: up to ``newton_steps`` Newton steps,
    each of up to CG_STEPS conjugate-gradient iterations, stopping once every spring that can move is within
    TOLERANCE of its limit; a step that leaves the largest excess larger is halved or undone. Returns how many
    springs that can move are still past the tolerance.

    x (k, 3) m; w (k,) 1/kg the inverse masses of the split (0: the point does not move); ends (s, 2) uint32
    and table (s, 5) the packed springs (``constraints.pack_springs``: l_max m in column 0); free_along (k,)
    bool: the points that move along their contact plane only (unit normals plane_normal (k, 3)); blocks (3,)
    int64: the springs' blocks (``blocks.split_springs``; where they may run on two threads, the scans for
    the springs over their limits do)."""
    n_s = ends.shape[0]
    act = np.empty(n_s, dtype=np.int64)
    dirs = np.empty((n_s, 3))
    c = np.empty(n_s)
    diag = np.empty(n_s)
    acc = np.zeros((x.shape[0], 3))
    base = x.copy()
    left = 0
    solves = 0
    halvings = 0
    merit_base = np.inf
    while True:
        m, left = _active(x, w, ends, table, free_along, plane_normal, act, dirs, c, diag, blocks)
        merit = 0.0
        for a in range(m):
            merit = max(merit, c[a] / table[act[a], 0])
        if merit > merit_base:
            # the last step overshot (far past the limits the linearisation is poor): half of it back
            if halvings == MAX_HALVINGS:
                x[:] = base
                m, left = _active(x, w, ends, table, free_along, plane_normal, act, dirs, c, diag, blocks)
                break
            x[:] = 0.5 * (x + base)
            halvings += 1
            continue
        if left == 0 or solves == newton_steps:
            break
        base[:] = x
        merit_base = merit
        halvings = 0
        solves += 1
        lam = np.zeros(m)
        r = c[:m].copy()
        precondition = 1.0 / (diag[:m] * (1.0 + REGULARISE))
        z = r * precondition
        p = z.copy()
        ap = np.empty(m)
        rz = r @ z
        r0 = math.sqrt(r @ r)
        for _ in range(CG_STEPS):
            _apply(m, act, ends, dirs, w, free_along, plane_normal, diag, p, acc, ap)
            pap = p @ ap
            if pap <= 0.0:
                break
            alpha = rz / pap
            lam += alpha * p
            r -= alpha * ap
            if math.sqrt(r @ r) < 1e-3 * r0:
                break
            z = r * precondition
            rz_new = r @ z
            p = z + (rz_new / rz) * p
            rz = rz_new
        # dx = -W J^T lambda, each moved point once
        _spread(m, act, ends, dirs, lam, acc)
        for a in range(m):
            s = act[a]
            for e in range(2):
                v = ends[s, e]
                if acc[v, 0] == 0.0 and acc[v, 1] == 0.0 and acc[v, 2] == 0.0:
                    continue
                ax, ay, az = _w_times(w, free_along, plane_normal, v, acc[v, 0], acc[v, 1], acc[v, 2])
                x[v, 0] -= ax
                x[v, 1] -= ay
                x[v, 2] -= az
                acc[v, 0] = 0.0
                acc[v, 1] = 0.0
                acc[v, 2] = 0.0
    return left


@njit(cache=True, nogil=True, fastmath=True)
def sticking(x, x_step, w, has_plane, plane_normal, out_w):
    """out_w (k,) = w, but 0 for the contact points that moved less than STICK_MOVE m along their plane since
    ``x_step`` (k, 3) m (where the step started): static friction holds them."""
    for i in range(x.shape[0]):
        out_w[i] = w[i]
        if not has_plane[i]:
            continue
        mx = x[i, 0] - x_step[i, 0]
        my = x[i, 1] - x_step[i, 1]
        mz = x[i, 2] - x_step[i, 2]
        mn = mx * plane_normal[i, 0] + my * plane_normal[i, 1] + mz * plane_normal[i, 2]
        tx = mx - mn * plane_normal[i, 0]
        ty = my - mn * plane_normal[i, 1]
        tz = mz - mn * plane_normal[i, 2]
        if tx * tx + ty * ty + tz * tz < STICK_MOVE * STICK_MOVE:
            out_w[i] = 0.0
