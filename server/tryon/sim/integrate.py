"""Verlet integration (paper eq. 1) with gravity and linear air drag."""

from __future__ import annotations

import math

from numba import njit, prange


@njit(cache=True, nogil=True, fastmath=True)
def verlet_step(x, x_prev, inv_mass, dt, gravity, air_drag, max_speed):
    """One Verlet step in place: x(t+dt) = x + (1 - c dt)(x - x_prev) + g dt^2 (eq. 1, F_ext/m = g plus
    the drag, written as a velocity factor so it can never reverse the velocity).

    x, x_prev (k, 3) m, modified in place (x_prev becomes the old x); inv_mass (k,) 1/kg, 0 = pinned
    (does not move); dt s; gravity m/s^2 (along -y); air_drag 1/s; max_speed m/s (displacement per step
    clamped to max_speed * dt, a guard against any blow-up).
    """
    damp = max(0.0, 1.0 - air_drag * dt)
    g = gravity * dt * dt
    limit = max_speed * dt
    for i in range(x.shape[0]):
        if inv_mass[i] == 0.0:
            x_prev[i, 0] = x[i, 0]
            x_prev[i, 1] = x[i, 1]
            x_prev[i, 2] = x[i, 2]
            continue
        vx = (x[i, 0] - x_prev[i, 0]) * damp
        vy = (x[i, 1] - x_prev[i, 1]) * damp - g
        vz = (x[i, 2] - x_prev[i, 2]) * damp
        s2 = vx * vx + vy * vy + vz * vz
        if s2 > limit * limit:
            f = limit / math.sqrt(s2)
            vx *= f
            vy *= f
            vz *= f
        x_prev[i, 0] = x[i, 0]
        x_prev[i, 1] = x[i, 1]
        x_prev[i, 2] = x[i, 2]
        x[i, 0] += vx
        x[i, 1] += vy
        x[i, 2] += vz


@njit(cache=True, nogil=True, fastmath=True)
def kinetic_energy_per_kg(x, x_prev, mass, dt):
    """Mean kinetic energy per kilogram, sum(m |v|^2 / 2) / sum(m), J/kg, with v = (x - x_prev) / dt."""
    e = 0.0
    m = 0.0
    for i in range(x.shape[0]):
        dx = x[i, 0] - x_prev[i, 0]
        dy = x[i, 1] - x_prev[i, 1]
        dz = x[i, 2] - x_prev[i, 2]
        e += mass[i] * (dx * dx + dy * dy + dz * dz)
        m += mass[i]
    if m <= 0.0:
        return 0.0
    return 0.5 * e / (m * dt * dt)


@njit(cache=True, nogil=True, parallel=True, fastmath=True)
def _verlet_halves(x, x_prev, inv_mass, dt, gravity, air_drag, max_speed):
    """``verlet_step`` (same arguments) on two threads, half the points each. No races: a point's step reads
    and writes only its own rows; the result is that of one call over all."""
    k = x.shape[0]
    half = k // 2
    for t in prange(2):
        lo = 0 if t == 0 else half
        hi = half if t == 0 else k
        verlet_step(x[lo:hi], x_prev[lo:hi], inv_mass[lo:hi], dt, gravity, air_drag, max_speed)


@njit(cache=True, nogil=True, fastmath=True)
def verlet_split(x, x_prev, inv_mass, dt, gravity, air_drag, max_speed, two):
    """``verlet_step``, on two threads if ``two`` (a garment whose springs run in two blocks,
    ``blocks.split_springs``), else on the calling thread."""
    if two:
        _verlet_halves(x, x_prev, inv_mass, dt, gravity, air_drag, max_speed)
    else:
        verlet_step(x, x_prev, inv_mass, dt, gravity, air_drag, max_speed)


@njit(cache=True, nogil=True, fastmath=True)
def keep_above_floor(x, x_prev, floor_y):
    """Points below the floor plane y = floor_y (m) are put on it, in place, with no downward velocity
    and their horizontal motion stopped (the floor holds cloth still: friction)."""
    for i in range(x.shape[0]):
        if x[i, 1] < floor_y:
            x[i, 1] = floor_y
            x_prev[i, 0] = x[i, 0]
            x_prev[i, 1] = floor_y
            x_prev[i, 2] = x[i, 2]
