"""Strain-limited springs as constraints (paper eq. 2-3, after Provot 1995)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, fastmath=True)
def satisfy_springs(x, inv_mass, springs, rest, kind, limit, compression, passes):
    """Project every spring onto its allowed length range, ``passes`` times, in place.

    x (k, 3) m; inv_mass (k,) 1/kg (0 = pinned, never moved); springs (s, 2) int32; rest (s,) m;
    kind (s,) int8; limit (3,) maximum strain per kind (l_max = rest (1 + limit)); compression (3,)
    fraction of the shortfall below the natural length corrected per pass, per kind.

    Eq. 3: V = (p_i - p_j) / |p_i - p_j| (|p_i - p_j| - l_target); p_i -= w_i / (w_i + w_j) V;
    p_j += w_j / (w_i + w_j) V, with l_target = l_max when the spring is too long, and rest (scaled by
    ``compression``) when it is too short.

    Serial Gauss-Seidel in spring order, forward on even passes and backward on odd ones (symmetric
    Gauss-Seidel): a correction travels the whole length of a chain in one pass in the direction of the
    sweep, so alternating lets hanging cloth feel its support within two passes whichever end that
    is. No races: one thread owns the whole loop (parallelism comes from running several try-ons at
    once, each kernel releasing the GIL).
    """
    n_springs = springs.shape[0]
    for sweep in range(passes):
        for q in range(n_springs):
            s = q if sweep % 2 == 0 else n_springs - 1 - q
            i = springs[s, 0]
            j = springs[s, 1]
            wi = inv_mass[i]
            wj = inv_mass[j]
            wsum = wi + wj
            if wsum == 0.0:
                continue
            dx = x[i, 0] - x[j, 0]
            dy = x[i, 1] - x[j, 1]
            dz = x[i, 2] - x[j, 2]
            d = math.sqrt(dx * dx + dy * dy + dz * dz)
            if d < 1e-12:
                continue
            k = kind[s]
            l0 = rest[s]
            lmax = l0 * (1.0 + limit[k])
            if d > lmax:
                excess = d - lmax
            elif d < l0:
                excess = (d - l0) * compression[k]
            else:
                continue
            f = excess / (d * wsum)
            x[i, 0] -= wi * f * dx
            x[i, 1] -= wi * f * dy
            x[i, 2] -= wi * f * dz
            x[j, 0] += wj * f * dx
            x[j, 1] += wj * f * dy
            x[j, 2] += wj * f * dz


@njit(cache=True, nogil=True, fastmath=True)
def spring_strain(x, springs, rest):
    """Strain l / l0 - 1 per spring, (s,) float64."""
    out = np.empty(springs.shape[0])
    for s in range(springs.shape[0]):
        i = springs[s, 0]
        j = springs[s, 1]
        dx = x[i, 0] - x[j, 0]
        dy = x[i, 1] - x[j, 1]
        dz = x[i, 2] - x[j, 2]
        out[s] = math.sqrt(dx * dx + dy * dy + dz * dz) / rest[s] - 1.0
    return out


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
