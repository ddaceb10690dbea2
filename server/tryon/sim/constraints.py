"""Strain-limited springs as constraints (paper eq. 2-3, after Provot 1995)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from tryon.sim.collision.contacts import project_listed, project_split


@njit(cache=True, nogil=True, fastmath=True)
def spring_lengths(x, springs):
    """Length of every spring, (s,) float64, m."""
    out = np.empty(springs.shape[0])
    for s in range(springs.shape[0]):
        i = springs[s, 0]
        j = springs[s, 1]
        dx = x[i, 0] - x[j, 0]
        dy = x[i, 1] - x[j, 1]
        dz = x[i, 2] - x[j, 2]
        out[s] = math.sqrt(dx * dx + dy * dy + dz * dz)
    return out


def folded_at(x: np.ndarray, springs: np.ndarray, rest: np.ndarray, below: float) -> np.ndarray:
    """(s,) bool: the ``springs`` (s, 2) int64 of x (n, 3) m shorter than (1 - ``below``) x their natural length
    ``rest`` (s,) m: cloth folded finer than the mesh shows (``Tuning.folded_below``)."""
    return spring_lengths(x, springs) < rest * (1.0 - below)


@njit(cache=True, nogil=True, fastmath=True)
def spring_strain(x, springs, rest):
    """Strain l / l0 - 1 per spring, (s,) float64."""
    return spring_lengths(x, springs) / rest - 1.0


def satisfy_springs_numpy(x, inv_mass, springs, rest, kind, limit, compression, passes):
    """Plain (slow, per-spring Python) version of :func:`satisfy_springs`: the test oracle."""
    x = x.copy()
    for sweep in range(passes):
        order = range(len(springs)) if sweep % 2 == 0 else range(len(springs) - 1, -1, -1)
        for s in order:
            i, j = springs[s]
            wsum = inv_mass[i] + inv_mass[j]
            if wsum == 0:
                continue
            delta = x[i] - x[j]
            d = np.linalg.norm(delta)
            lmax = rest[s] * (1 + limit[kind[s]])
            if d > lmax:
                excess = d - lmax
            elif d < rest[s]:
                excess = (d - rest[s]) * compression[kind[s]]
            else:
                continue
            v = delta / d * excess
            x[i] -= inv_mass[i] / wsum * v
            x[j] += inv_mass[j] / wsum * v
    return x


# A spring steeper than this (|dy| / length, sin 30 degrees) has an upper and a lower end in the
# top-down sweep; flatter ones are split by inverse mass (no sideways bias, so no drift).
STEEP = 0.5


@njit(cache=True, nogil=True)
def top_down_order(x, springs, steep_only=True):
    """Spring indices (q,) int64 sorted by the height of their upper end, highest first (a stable sort:
    ties keep spring order); with ``steep_only`` only the springs steeper than STEEP / 2 now (the sweep's
    flat springs are the symmetric passes' job, and the order is refreshed every few steps), which halves
    the sweep. A kernel: with numpy's argsort and fancy indexing it cost ~2 ms a call on the perf T-shirt."""
    n = springs.shape[0]
    top = np.empty(n)
    for s in range(n):
        top[s] = -max(x[springs[s, 0], 1], x[springs[s, 1], 1])
    order = np.argsort(top, kind="mergesort")
    if not steep_only:
        return order
    keep = np.empty(n, dtype=np.int64)
    m = 0
    for q in range(n):
        s = order[q]
        i = springs[s, 0]
        j = springs[s, 1]
        dx = x[i, 0] - x[j, 0]
        dy = x[i, 1] - x[j, 1]
        dz = x[i, 2] - x[j, 2]
        if abs(dy) >= 0.5 * STEEP * math.sqrt(dx * dx + dy * dy + dz * dz):
            keep[m] = s
            m += 1
    return keep[:m].copy()


# Of the median natural length: a spring shorter than this is a sliver's (see ``cap_stretch``). The 200
# scenes of ``tryon bench --stress`` pass with a quarter or a half; with a half, an irregular real garment
# (the MakeHuman blouse outfit, many short springs, too small for the medium body) no longer came to rest,
# the guard fighting the collision.
SHORT_SPRING = 0.25
# Relative slack of ``cap_stretch``'s test (on the squared length): a spring the guard has just put back at its
# cap is found at cap x (1 + 1e-16) by rounding, so without it every sweep "found" one and the guard ran all
# its sweeps on every step where a spring had reached the cap (100 instead of 2-3: a third of a tucked-in
# outfit's time, ``tryon bench --only outfits``).
CAP_SLACK = 1e-9


@njit(cache=True, nogil=True, fastmath=True)
def _cap_sweeps(x, inv_mass, springs, rest, cap, max_passes):
    """``cap_stretch``'s sweeps over the springs given; returns the sweeps done."""
    for sweep in range(max_passes):
        found = False
        n_springs = springs.shape[0]
        for q in range(n_springs):
            s = n_springs - 1 - q if sweep % 2 == 1 else q
            i = springs[s, 0]
            j = springs[s, 1]
            wsum = inv_mass[i] + inv_mass[j]
            if wsum == 0.0:
                continue
            dx = x[i, 0] - x[j, 0]
            dy = x[i, 1] - x[j, 1]
            dz = x[i, 2] - x[j, 2]
            d2 = dx * dx + dy * dy + dz * dz
            lmax = cap * rest[s]
            if d2 <= lmax * lmax * (1.0 + CAP_SLACK):
                continue
            d = math.sqrt(d2)
            found = True
            f = (d - lmax) / (d * wsum)
            x[i, 0] -= inv_mass[i] * f * dx
            x[i, 1] -= inv_mass[i] * f * dy
            x[i, 2] -= inv_mass[i] * f * dz
            x[j, 0] += inv_mass[j] * f * dx
            x[j, 1] += inv_mass[j] * f * dy
            x[j, 2] += inv_mass[j] * f * dz
        if not found:
            return sweep + 1
    return max_passes


@njit(cache=True, nogil=True, fastmath=True)
def cap_stretch(x, inv_mass, springs, rest, cap, max_passes):
    """Shorten every spring longer than ``cap`` x its natural length back to it (inverse-mass split),
    sweeping until a pass finds none or ``max_passes`` sweeps, in place; returns the sweeps done.
    A guard, not a material law: one cheap sweep when nothing is that long (the normal case)."""
    sweeps = _cap_sweeps(x, inv_mass, springs, rest, cap, max_passes)
    if sweeps < max_passes:
        return sweeps
    # out of sweeps: short springs (slivers the simplification left: 1-3 mm among 3 cm ones) may be left
    # far past the cap, their ends pulled by the long springs corrected after them in every sweep. Alone
    # they settle within a few sweeps, moving points by millimetres. (The long springs left over the cap
    # are not swept again: a garment far too small for its body, where collision and the guard fight,
    # would then never come to rest.)
    short = SHORT_SPRING * np.median(rest)
    over = np.empty(springs.shape[0], dtype=np.int64)
    n_over = 0
    for s in range(springs.shape[0]):
        if rest[s] >= short:
            continue
        i = springs[s, 0]
        j = springs[s, 1]
        d2 = (x[i, 0] - x[j, 0]) ** 2 + (x[i, 1] - x[j, 1]) ** 2 + (x[i, 2] - x[j, 2]) ** 2
        if d2 > (cap * rest[s]) ** 2 * (1.0 + CAP_SLACK):
            over[n_over] = s
            n_over += 1
    if n_over:
        keep = over[:n_over]
        _cap_sweeps(x, inv_mass, springs[keep], rest[keep], cap, max_passes)
    return max_passes


# --- springs packed one row each: what the loop's passes and sweep read --------------------------------

def pack_springs(springs: np.ndarray, rest: np.ndarray, kind: np.ndarray, limit: np.ndarray,
                 compression: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ends (s, 2) uint32, table (s, 5) float64) for the packed kernels: table rows are (l_max m, rest m,
    compression fraction, most a pass lengthens a compressed spring by, m: 0 = no cap; a re-posed drape's,
    ``tuning.unfold_per_pass``; the spring's elasticity k h^2 per pass, kg: 0 = none, set by the drape's
    ``start`` from the fabric). One row per spring instead of a kind lookup into two tables (and
    squared-length tests): the passes ran ~20 % faster on a draped T-shirt (``python3 -m tryon.bench.perf``)."""
    # unsigned: numba then indexes without the negative-index wrap-around (the passes ~4 % faster)
    ends = np.ascontiguousarray(springs, dtype=np.uint32)
    kind = np.asarray(kind, dtype=np.int64)
    table = np.zeros((len(ends), 5))
    table[:, 0] = rest * (1.0 + np.asarray(limit)[kind])
    table[:, 1] = rest
    table[:, 2] = np.asarray(compression)[kind]
    return ends, table


@njit(cache=True, nogil=True, fastmath=True, boundscheck=False, error_model="numpy")
def _spring_pass(x, inv_mass, ends, table, backward, relax):
    """One Gauss-Seidel pass over packed springs (``pack_springs``), forward or backward, in place.

    A spring longer than its natural length l0 is shortened by min(1, k h^2 w) of its stretch l - l0, w = w_i +
    w_j split by inverse mass (``table[:, 4]`` = k h^2 per pass, kg, from the fabric's stiffness,
    ``garment.fabric``): XPBD with compliance 1 / (k h^2) - w, one pass from a zero multiplier. One such pass a
    substep holds a tension T at a stretch of T (1 / k + h^2 w): the restart from a zero multiplier adds the
    compliance h^2 w to the fabric's (Macklin et al. 2016's non-converged XPBD; a knit at the default settings,
    k h^2 w ~ 1.8, hung 2.3x its fabric's stretch), taken back here from the compliance; a fabric stiffer than one
    pass can hold (k h^2 w > 1: a woven) is corrected whole, as PBD. And always at least back to l_max (the strain
    limit, where the fabric locks: eq. 3). A shorter one is pushed back by the compression fraction of
    its shortfall. A spring without stiffness within its range costs no square root.

    An unsigned spring index (no negative-index wrap-around) and numpy's error model (no zero-division
    check: the division is guarded) make a step's passes ~5 % faster on the perf T-shirt, same results."""
    n_springs = ends.shape[0]
    for q in range(n_springs):
        s = np.uint32(n_springs - 1 - q) if backward else np.uint32(q)
        i = ends[s, 0]
        j = ends[s, 1]
        dx = x[i, 0] - x[j, 0]
        dy = x[i, 1] - x[j, 1]
        dz = x[i, 2] - x[j, 2]
        d2 = dx * dx + dy * dy + dz * dz
        lmax = table[s, 0]
        l0 = table[s, 1]
        k = table[s, 4]
        wi = inv_mass[i]
        wj = inv_mass[j]
        wsum = wi + wj
        if d2 > l0 * l0:
            if k == 0.0 and d2 <= lmax * lmax:
                continue
            d = math.sqrt(d2)
            excess = max(d - lmax, (d - l0) * min(1.0, k * wsum))
        elif d2 < l0 * l0:
            d = math.sqrt(d2)
            excess = (d - l0) * table[s, 2]
            cap = table[s, 3]
            if cap > 0.0 and excess < -cap:
                excess = -cap
        else:
            continue
        if wsum == 0.0 or d < 1e-12:
            continue
        f = relax * excess / (d * wsum)
        x[i, 0] -= wi * f * dx
        x[i, 1] -= wi * f * dy
        x[i, 2] -= wi * f * dz
        x[j, 0] += wj * f * dx
        x[j, 1] += wj * f * dy
        x[j, 2] += wj * f * dz


@njit(cache=True, nogil=True, fastmath=True)
def solve_constraints(x, x_prev, inv_mass, ends, table, passes, has_plane, plane_point, plane_normal,
                      mu_static, mu_kinetic, push, relax=1.0):
    """``passes`` Gauss-Seidel passes over the springs (``satisfy_springs``), each followed by the contact
    planes (``project_planes``), in place.

    Contacts found once per step (the expensive map query) become planes that every pass respects, so
    springs and contacts converge together instead of undoing each other's work (the way position-based
    solvers such as NVIDIA Flex handle contacts).
    """
    solve_listed(x, x_prev, inv_mass, ends, table, passes, np.flatnonzero(has_plane), plane_point, plane_normal,
                 mu_static, mu_kinetic, push, relax)


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def _two_blocks(x, inv_mass, ends, table, na, nb, backward, relax):
    """One pass over the blocks A = springs [0, na) and B = [na, na + nb) at once, one thread each
    (``blocks.split_springs``). No races: no point is an end of springs in both blocks, so each thread
    writes only its own block's points; the result is that of A then B on one thread."""
    for t in prange(2):
        if t == 0:
            _spring_pass(x, inv_mass, ends[:na], table[:na], backward, relax)
        else:
            _spring_pass(x, inv_mass, ends[na:na + nb], table[na:na + nb], backward, relax)


@njit(cache=True, nogil=True, fastmath=True)
def _blocked_pass(x, inv_mass, ends, table, blocks, backward, relax):
    """One pass over springs in block order (``blocks.split_springs``: [A | B | boundary], ``blocks`` (3,)
    int64 = (len A, len B, two threads allowed)): A and B (on two threads if allowed), then the boundary;
    backward, the boundary first. Blocks (0, 0, 0): one serial pass over all, as ``_spring_pass``."""
    na = blocks[0]
    nb = blocks[1]
    m = na + nb
    if m == 0:
        _spring_pass(x, inv_mass, ends, table, backward, relax)
        return
    if backward:
        _spring_pass(x, inv_mass, ends[m:], table[m:], True, relax)
    if blocks[2]:
        _two_blocks(x, inv_mass, ends, table, na, nb, backward, relax)
    else:
        _spring_pass(x, inv_mass, ends[:na], table[:na], backward, relax)
        _spring_pass(x, inv_mass, ends[na:m], table[na:m], backward, relax)
    if not backward:
        _spring_pass(x, inv_mass, ends[m:], table[m:], False, relax)


# one serial block: what ``solve_listed`` and the kernels calling it use when no blocks are given
ONE_BLOCK = np.zeros(3, dtype=np.int64)


@njit(cache=True, nogil=True, fastmath=True)
def solve_listed(x, x_prev, inv_mass, ends, table, passes, listed, plane_point, plane_normal, mu_static,
                 mu_kinetic, push, relax=1.0, blocks=ONE_BLOCK):
    """``solve_constraints`` with the contact planes of the points ``listed`` (q,) int64 (those with a
    plane, increasing): the same result, the projections visiting only the points in contact. ``blocks``:
    the springs' blocks (``_blocked_pass``; where they may run on two threads, so do the projections)."""
    for sweep in range(passes):
        _blocked_pass(x, inv_mass, ends, table, blocks, sweep % 2 == 1, relax)
        project_split(x, x_prev, listed, plane_point, plane_normal, mu_static, mu_kinetic, push, blocks[2] != 0)


@njit(cache=True, nogil=True, fastmath=True)
def satisfy_springs(x, inv_mass, ends, table, passes):
    """Project every spring onto its allowed length range, ``passes`` times, in place.

    x (k, 3) m; inv_mass (k,) 1/kg (0 = pinned, never moved); ends (s, 2) uint32 and table (s, 5) from
    ``pack_springs`` (l_max = rest (1 + limit of its kind); compression: the fraction of the shortfall
    below the natural length corrected per pass).

    Eq. 3: V = (p_i - p_j) / |p_i - p_j| (|p_i - p_j| - l_target); p_i -= w_i / (w_i + w_j) V;
    p_j += w_j / (w_i + w_j) V, with l_target = l_max when the spring is too long, and rest (scaled by
    ``compression``) when it is too short.

    Serial Gauss-Seidel in spring order, forward on even passes and backward on odd ones (symmetric
    Gauss-Seidel): a correction travels the whole length of a chain in one pass in the direction of the
    sweep, so alternating lets hanging cloth feel its support within two passes whichever end that
    is. No races: one thread owns the whole loop (parallelism comes from running several try-ons at
    once, each kernel releasing the GIL).
    """
    for sweep in range(passes):
        _spring_pass(x, inv_mass, ends, table, sweep % 2 == 1, 1.0)


def limit_stretch_downward(x, x_prev, inv_mass, ends, table, order, touching):
    """The top-down sweep (``sweep_downward``) of the packed springs ``ends`` / ``table`` in ``order``
    (q,) int64 (e.g. ``top_down_order``)."""
    sweep_ends, sweep_lmax = pack_sweep(ends, table, order)
    sweep_downward(x, x_prev, inv_mass, sweep_ends, sweep_lmax, touching)


@njit(cache=True, nogil=True)
def pack_sweep(ends, table, order):
    """(ends (q, 2) uint32, l_max (q,) float64) of the springs ``order`` (q,) int64 in that order: what the
    sweep reads, one contiguous row per visit instead of two scattered lookups (the sweep ran ~10 %
    faster on a draped T-shirt, ``python3 -m tryon.bench.perf``)."""
    sweep_ends = np.empty((order.shape[0], 2), dtype=np.uint32)
    sweep_lmax = np.empty(order.shape[0])
    for q in range(order.shape[0]):
        s = order[q]
        sweep_ends[q, 0] = ends[s, 0]
        sweep_ends[q, 1] = ends[s, 1]
        sweep_lmax[q] = table[s, 0]
    return sweep_ends, sweep_lmax


@njit(cache=True, nogil=True)
def _kept(ends, lmax, keep, blocks):
    """(ends (q, 2) uint32, l_max (q,), blocks (3,) int64) of the springs ``ends`` (s, 2) / ``lmax`` (s,) m with
    ``keep`` (s,) int64 1, in order, and their blocks (``blocks`` (3,): those of ``ends``, A = [0, blocks[0]),
    B = the next blocks[1], then the boundary). One pass that writes every spring and keeps it by counting it:
    no branch on which are kept, a pattern of contacts the processor cannot guess (a counting pass and a filling
    pass, each branching on it, took 128 instead of 15 us to pick a T-shirt M's sweep springs)."""
    n = ends.shape[0]
    out_ends = np.empty((n, 2), dtype=np.uint32)
    out_lmax = np.empty(n)
    a_end, b_end = blocks[0], blocks[0] + blocks[1]
    before_a, before_b = -1, -1
    m = 0
    for s in range(n):
        if s == a_end:
            before_a = m
        if s == b_end:
            before_b = m
        out_ends[m, 0] = ends[s, 0]
        out_ends[m, 1] = ends[s, 1]
        out_lmax[m] = lmax[s]
        m += keep[s]
    counts = np.zeros(3, dtype=np.int64)
    counts[0] = before_a if before_a >= 0 else m
    counts[1] = (before_b if before_b >= 0 else m) - counts[0]
    counts[2] = blocks[2]
    return out_ends[:m].copy(), out_lmax[:m].copy(), counts


@njit(cache=True, nogil=True)
def contact_springs(ends, table, on_body, blocks=ONE_BLOCK):
    """(ends (b, 2) uint32, table (b, 5), blocks (3,) int64) of the springs with both ends on the body
    (``on_body`` (k,) bool), in spring order, stretch only (l0 = 0 and no compression: cloth pressed on the
    body must stay free to buckle, and a compressed spring is not even visited for a zero correction): the
    contact passes' springs, and their blocks (``blocks``: those of ``ends``; the selection keeps the block
    order). A kernel (``_kept``): the same selection by numpy fancy indexing cost ~0.3 ms per step on the perf
    T-shirt (``python3 -m tryon.bench.perf``)."""
    keep = np.empty(ends.shape[0], dtype=np.int64)
    for s in range(ends.shape[0]):
        keep[s] = np.int64(on_body[ends[s, 0]]) & np.int64(on_body[ends[s, 1]])
    body_ends, lmax, body_blocks = _kept(ends, table[:, 0], keep, blocks)
    body_table = np.zeros((len(lmax), 5))
    body_table[:, 0] = lmax
    return body_ends, body_table, body_blocks


@njit(cache=True, nogil=True)
def sweep_springs(sweep_ends, sweep_lmax, on_body, hangs, blocks=ONE_BLOCK):
    """The springs of a packed sweep (``pack_sweep``) with an end off the body (``on_body`` (k,) bool) and
    in cloth that hangs from something (``hangs`` (k,) bool: ``hanging_pieces``), in the same order:
    springs with both ends on the body are the contact passes' job (the sweep would only split them by
    inverse mass: one more stretch pass over them), and a piece that touches nothing must fall (the
    sweep's lift only pulls lower ends up, so it would hold the piece in the air). Returns (ends (q, 2)
    uint32, l_max (q,), blocks (3,) int64: those of the kept springs, ``blocks`` being the sweep's
    (``block_order``); ``_kept``)."""
    keep = np.empty(sweep_ends.shape[0], dtype=np.int64)
    for q in range(sweep_ends.shape[0]):
        i = sweep_ends[q, 0]
        keep[q] = np.int64(hangs[i]) & (1 - (np.int64(on_body[i]) & np.int64(on_body[sweep_ends[q, 1]])))
    return _kept(sweep_ends, sweep_lmax, keep, blocks)


@njit(cache=True, nogil=True, fastmath=True, boundscheck=False)
def sweep_downward(x, x_prev, inv_mass, sweep_ends, sweep_lmax, touching):
    """One sweep of the stretch limits of the springs ``sweep_ends`` (q, 2) uint32 / ``sweep_lmax`` (q,) m,
    sorted from the top down (``pack_sweep``), moving only the lower end of each too-long steep spring
    (the upper one if the lower is pinned), in place (in the spirit of follow-the-leader, Mueller et al.
    2012): straight up, never above where it started the substep (a guard against sagging, not a lifter),
    leaving it no upward velocity (x_prev (k, 3)). Only a free lower end follows: where it touches the
    body (``touching`` (k,) bool, e.g. a sleeve around an arm) the cloth does not hang, and pulling it up
    would ratchet a tight garment up the body; such springs are split by inverse mass.

    Garments hang from their top (shoulders, waist): corrected from the support down, each correction
    sees an already corrected upper end, so a hanging chain of any length is within its limits after
    one sweep, where mass-weighted Gauss-Seidel needs a number of passes that grows with the square of
    its length (a sagging, over-stretched hem). Only stretch is limited here (compression is the
    symmetric passes' job). No races: serial.
    """
    for q in range(sweep_ends.shape[0]):
        i = sweep_ends[q, 0]
        j = sweep_ends[q, 1]
        dx = x[j, 0] - x[i, 0]
        dy = x[j, 1] - x[i, 1]
        dz = x[j, 2] - x[i, 2]
        d2 = dx * dx + dy * dy + dz * dz
        lmax = sweep_lmax[q]
        if d2 <= lmax * lmax:
            continue
        if x[i, 1] < x[j, 1]:
            i, j = j, i  # i is the upper end
            dx = -dx
            dy = -dy
            dz = -dz
        if inv_mass[j] == 0.0:
            if inv_mass[i] == 0.0:
                continue
            i, j = j, i
            dx = -dx
            dy = -dy
            dz = -dz
        d = math.sqrt(d2)
        if d < 1e-12:
            continue
        f = (d - lmax) / d
        if abs(dy) >= STEEP * d and not touching[j]:
            lift = (d - lmax) * d / abs(dy)
            fell = x_prev[j, 1] - x[j, 1]
            lift = min(lift, max(fell, 0.0))
            x[j, 1] += lift
            if x[j, 1] > x_prev[j, 1]:
                x_prev[j, 1] = x[j, 1]
        else:
            wi = inv_mass[i]
            wj = inv_mass[j]
            wsum = wi + wj
            a = wi / wsum * f
            b = wj / wsum * f
            x[i, 0] += a * dx
            x[i, 1] += a * dy
            x[i, 2] += a * dz
            x[j, 0] -= b * dx
            x[j, 1] -= b * dy
            x[j, 2] -= b * dz
