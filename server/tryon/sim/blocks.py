"""Two threads for one drape: the springs in two blocks that share no point, and the springs between them.

A pass over the springs (``constraints._spring_pass``) is serial Gauss-Seidel: each correction sees the ones
before it, which is what carries a correction along a whole chain in one pass. To run it on two cores without
changing that, the garment's points are cut in two halves at the median of their longest extent (on the
garment's rest shape); the springs with both ends in one half form that half's block, the few that cross the
cut (one row of a cloth) the boundary. The two blocks write disjoint points, so they run at the same time on
two threads with no race, and the numbers are those of one thread running block A, then block B: the same
on one thread or two, whatever the machine's load. The boundary springs run after them (before them on a
backward pass). Within a block the springs keep the garment's own order.

Only garments with at least ``MIN_SPLIT_SPRINGS`` springs are split: a parallel launch costs a few
microseconds, and the catalogue's garments (at most 12,480 springs, the XXL dress; ~0.1 ms a pass) keep
their one block and their drapes bit for bit. The body collision of such a garment's points also runs on two
threads, half the points each (``collide_halves``), and so does the step's depth test (``depth_halves``). How
many threads a launch uses is the caller's thread setting (``numba.set_num_threads``: the service's pool gives a
try-on both cores while it runs alone, one each when two run at once, ``api.pool``); where no thread-safe
threading layer loads (OpenMP or TBB: the pool's threads launch kernels at the same time), the blocks run one
after the other on the calling thread.
"""

from __future__ import annotations

import functools
import os
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

import numba
import numpy as np
from numba import njit, prange

from tryon.sim.collision.kernels import collide_points, penetration_depth
from tryon.sim.constraints import sweep_downward

# springs: a garment with fewer keeps one block (the perf T-shirt has 16,938, the catalogue at most 12,480)
MIN_SPLIT_SPRINGS = 15_000

if "NUMBA_THREADING_LAYER" not in os.environ:
    # the pool's worker threads launch parallel kernels at once: only OpenMP and TBB allow that
    numba.config.THREADING_LAYER = "threadsafe"


@functools.cache
def parallel_ok() -> bool:
    """Whether a parallel kernel can run here (a thread-safe threading layer loads); probed once."""
    try:
        return bool(probe_parallel(np.zeros(2)) == 2.0)
    except (ValueError, ImportError, RuntimeError):  # no thread-safe layer on this machine
        return False


def split_springs(springs: np.ndarray, points: np.ndarray,
                  min_springs: int = MIN_SPLIT_SPRINGS) -> tuple[np.ndarray, np.ndarray]:
    """(order (s,) int64, blocks (3,) int64): the springs (s, 2) in block order, [block A | block B |
    boundary], and (size of A, size of B, 1 if the blocks may run on two threads). ``points`` (k, 3) m: the
    shape the cut is made on (the garment at rest). Under ``min_springs`` springs: the identity order and
    blocks (0, 0, 0) (one serial block, as before)."""
    s = len(springs)
    if s < min_springs or len(points) < 2:
        return np.arange(s, dtype=np.int64), np.zeros(3, dtype=np.int64)
    extent = points.max(axis=0) - points.min(axis=0)
    coord = points[:, int(np.argmax(extent))]
    upper = coord >= np.median(coord)
    ends_upper = upper[springs]
    in_a = ~ends_upper[:, 0] & ~ends_upper[:, 1]
    in_b = ends_upper[:, 0] & ends_upper[:, 1]
    order = np.concatenate([np.flatnonzero(in_a), np.flatnonzero(in_b), np.flatnonzero(~(in_a | in_b))])
    blocks = np.array([in_a.sum(), in_b.sum(), int(parallel_ok())], dtype=np.int64)
    return order.astype(np.int64), blocks


def machine_threads() -> int:
    """Threads a parallel kernel may use on this machine (numba's, the cores unless NUMBA_NUM_THREADS)."""
    return int(numba.config.NUMBA_NUM_THREADS)


# the pool of ``at_once``: three threads (an outfit's garments, a size advice's three sizes, step in lockstep or
# side by side); made at the first call
_AT_ONCE_WORKERS = 3
_AT_ONCE: ThreadPoolExecutor | None = None


def at_once(fn: Callable, items: list) -> list:
    """``[fn(item) for item in items]``, the items at once (one thread each, each held to one numba thread) when
    there are several and the calling thread may use two threads or more, else one after the other. ``fn`` must
    touch only what belongs to its item (a drape: its model, state and control): then the results are the same
    either way, as the kernels release the GIL and read the shared body without writing it."""
    global _AT_ONCE
    if len(items) < 2 or numba.get_num_threads() < 2:
        return [fn(item) for item in items]
    if _AT_ONCE is None:
        _AT_ONCE = ThreadPoolExecutor(max_workers=_AT_ONCE_WORKERS, thread_name_prefix="tryon-at-once")

    def alone(item):
        use_threads(1)
        return fn(item)

    return list(_AT_ONCE.map(alone, items))


def use_threads(n: int) -> int:
    """Let the calling thread's parallel kernels use ``n`` threads (at most ``machine_threads``, at least
    one; numba's setting is per calling thread); returns the number set."""
    n = max(1, min(int(n), machine_threads()))
    numba.set_num_threads(n)
    return n


@njit(cache=True, nogil=True, parallel=True)
def probe_parallel(a):
    """A trivial parallel kernel (``blocks.parallel_ok`` runs it once): the sum of a + 1 over a (2,)."""
    total = 0.0
    for i in prange(a.shape[0]):
        total += a[i] + 1.0
    return total


@njit(cache=True, nogil=True)
def block_order(order, blocks):
    """(order (q,) int64, blocks (3,) int64): spring indices ``order`` (q,) (into springs in block order,
    ``blocks.split_springs``: A = [0, blocks[0]), B = the next blocks[1], then the boundary) regrouped as
    [A's | B's | the boundary's], each group in its given order (a top-down sweep stays top-down within
    each), and the groups' sizes (the third entry copied)."""
    na = blocks[0]
    m = blocks[0] + blocks[1]
    out = np.empty_like(order)
    sizes = np.zeros(3, dtype=np.int64)
    sizes[2] = blocks[2]
    for q in range(order.shape[0]):
        if order[q] < na:
            sizes[0] += 1
        elif order[q] < m:
            sizes[1] += 1
    a, b, c = 0, sizes[0], sizes[0] + sizes[1]
    for q in range(order.shape[0]):
        s = order[q]
        if s < na:
            out[a] = s
            a += 1
        elif s < m:
            out[b] = s
            b += 1
        else:
            out[c] = s
            c += 1
    return out, sizes


@njit(cache=True, nogil=True, parallel=True)
def _two_sweeps(x, x_prev, inv_mass, sweep_ends, sweep_lmax, touching, na, nb):
    """The top-down sweeps of blocks A = [0, na) and B = [na, na + nb) at once, one thread each. No races:
    no point is an end of springs in both blocks (``blocks.split_springs``)."""
    for t in prange(2):
        if t == 0:
            sweep_downward(x, x_prev, inv_mass, sweep_ends[:na], sweep_lmax[:na], touching)
        else:
            sweep_downward(x, x_prev, inv_mass, sweep_ends[na:na + nb], sweep_lmax[na:na + nb], touching)


@njit(cache=True, nogil=True)
def sweep_blocked(x, x_prev, inv_mass, sweep_ends, sweep_lmax, touching, blocks):
    """``sweep_downward`` over a sweep in block order (``block_order``, ``blocks`` (3,) int64): blocks A and
    B (on two threads if allowed), then the boundary's springs. Blocks (0, 0, 0): one serial sweep."""
    na = blocks[0]
    m = blocks[0] + blocks[1]
    if m == 0:
        sweep_downward(x, x_prev, inv_mass, sweep_ends, sweep_lmax, touching)
        return
    if blocks[2]:
        _two_sweeps(x, x_prev, inv_mass, sweep_ends, sweep_lmax, touching, na, blocks[1])
    else:
        sweep_downward(x, x_prev, inv_mass, sweep_ends[:na], sweep_lmax[:na], touching)
        sweep_downward(x, x_prev, inv_mass, sweep_ends[na:m], sweep_lmax[na:m], touching)
    sweep_downward(x, x_prev, inv_mass, sweep_ends[m:], sweep_lmax[m:], touching)


@njit(cache=True, nogil=True, parallel=True)
def collide_halves(x, x_prev, inv_mass, active, parts, surface, lam, mu_static, mu_kinetic, contact, near,
                   has_plane, plane_point, plane_normal, hold_pinched, held, hold_depth):
    """``collision.kernels.collide_points`` (same arguments, ``held`` given) on two threads: the points
    [0, k/2) on one, the rest on the other. No races: a point's test reads only the body surface and writes
    only its own rows, so each thread writes its own half; the result is that of one call over all."""
    n = x.shape[0]
    half = n // 2
    moved = np.zeros(2, dtype=np.int64)
    for t in prange(2):
        lo = 0 if t == 0 else half
        hi = half if t == 0 else n
        moved[t] = collide_points(x[lo:hi], x_prev[lo:hi], inv_mass[lo:hi], active[lo:hi], parts, surface, lam,
                                  mu_static, mu_kinetic, contact[lo:hi], near, has_plane[lo:hi], plane_point[lo:hi],
                                  plane_normal[lo:hi], hold_pinched, held[lo:hi], hold_depth)
    return moved[0] + moved[1]


@njit(cache=True, nogil=True, parallel=True)
def depth_halves(points, parts, surface):
    """``collision.kernels.penetration_depth`` (same arguments) on two threads: the points [0, n/2) on one,
    the rest on the other. No races: a point's depth reads only the body surface and each thread writes its
    own half of the answer; the result is that of one call over all."""
    n = points.shape[0]
    half = n // 2
    out = np.empty(n)
    for t in prange(2):
        lo = 0 if t == 0 else half
        hi = half if t == 0 else n
        out[lo:hi] = penetration_depth(points[lo:hi], parts, surface)
    return out
