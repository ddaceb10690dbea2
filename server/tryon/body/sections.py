"""The torso's horizontal sections as the arm-press test reads them (``build.arm_press``), each built once.

Building a body in a pose whose arms would pass into the torso (``hands_on_hips``, arms hanging straight)
raises each arm by bisection on its angle, ~10 tests a side, each measuring how deep the arm's points go
into the convex hull of the torso's horizontal section at their height (rounded to ``step``). The torso does
not change meanwhile, so each height's hull is made once (``SectionHulls.depths``) instead of at every test:
~130 ms of the ``hands_on_hips`` body's 150 ms went to making the same hulls again. The depths are the same
to the bit (the same kernels on the same numbers).

Nor does the torso change with the pose: a live session's re-poses, a motion's poses and the poses bench build
bodies of the same measurements in pose after pose, and each made the same hulls again (~9 ms of a 20 ms body).
``section_hulls`` keeps the last few meshes' hulls, found by the bytes of their vertices (an exact match: a
different torso, to the last bit, makes its own).
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict

import numpy as np
from numba import njit

from tryon.body.kernels import convex_hull_2d, section_points_2d


@njit(cache=True)
def _section_hull(vertices: np.ndarray, edges: np.ndarray, level: int, step: float) -> np.ndarray:
    """(m, 2) counter-clockwise hull of the section of the mesh edges (e, 2) at height ``level * step`` m, in the
    section's (x, -z) (as ``plane_basis`` gives); empty for fewer than 3 section points."""
    up = np.array([0.0, 1.0, 0.0])
    basis = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    section = section_points_2d(vertices, edges, np.array([0.0, level * step, 0.0]), up, basis, 1e-10)
    return convex_hull_2d(section)


@njit(cache=True)
def _level_of(points: np.ndarray, step: float) -> np.ndarray:
    level = np.empty(points.shape[0], np.int64)
    for p in range(points.shape[0]):
        level[p] = np.int64(np.round(points[p, 1] / step))
    return level


@njit(cache=True)
def _hull_depths(points: np.ndarray, slot: np.ndarray, start: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """(n,) depth (m) of each point (n, 3) inside its hull (corners[start[slot[p]]:start[slot[p] + 1]], (m, 2)
    counter-clockwise): the distance to the hull's nearest edge line, 0 outside or for a hull of < 3 corners."""
    n = points.shape[0]
    depth = np.zeros(n)
    for p in range(n):
        a, b = start[slot[p]], start[slot[p] + 1]
        m = b - a
        if m < 3:
            continue
        inside = np.inf
        for c in range(m):  # counter-clockwise: the inward normal is the edge turned left
            i, j = a + c, a + (c + 1) % m
            e0 = corners[j, 0] - corners[i, 0]
            e1 = corners[j, 1] - corners[i, 1]
            length = np.sqrt(e0 * e0 + e1 * e1)
            if length == 0.0:
                continue
            dist = (-e1 * (points[p, 0] - corners[i, 0]) + e0 * (-points[p, 2] - corners[i, 1])) / length
            inside = min(inside, dist)
            if inside <= 0.0:
                break  # outside this edge: outside the hull (depth 0), whatever the other edges say
        depth[p] = max(inside, 0.0)
    return depth


class SectionHulls:
    """The convex hulls of the horizontal sections of one mesh (its ``vertices`` (v, 3) m and ``edges`` (e, 2)),
    every ``step`` m of height, made as they are first asked for and kept."""

    def __init__(self, vertices: np.ndarray, edges: np.ndarray, step: float):
        self.vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        self.edges = edges
        self.step = float(step)
        self.hulls: dict[int, np.ndarray] = {}

    def depths(self, points: np.ndarray) -> np.ndarray:
        """(n,) depth (m) of each point (n, 3) inside the convex hull of the section at its height rounded to
        ``step`` m (distance to the hull's nearest edge line), 0 outside."""
        points = np.ascontiguousarray(points, dtype=np.float64)
        if len(points) == 0:
            return np.zeros(0)
        levels, slot = np.unique(_level_of(points, self.step), return_inverse=True)
        hulls = []
        for level in levels.tolist():
            if level not in self.hulls:
                self.hulls[level] = _section_hull(self.vertices, self.edges, level, self.step)
            hulls.append(self.hulls[level])
        start = np.zeros(len(hulls) + 1, dtype=np.int64)
        start[1:] = np.cumsum([len(h) for h in hulls])
        return _hull_depths(points, slot.astype(np.int64), start, np.concatenate(hulls))


# meshes whose hulls are kept (a live session's torso and its grown copy, a few sessions at once)
KEPT_MESHES = 8
_kept: OrderedDict = OrderedDict()
_kept_lock = threading.Lock()


def section_hulls(vertices: np.ndarray, edges: np.ndarray, step: float) -> SectionHulls:
    """A ``SectionHulls`` of the mesh (``vertices`` (v, 3) m, ``edges`` (e, 2), every ``step`` m): the one made
    for the same vertices, edges and step before if it is among the last ``KEPT_MESHES``, else a new one. Any
    thread (its hulls dict only ever gains the same hull for a level)."""
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    digest = hashlib.blake2b(vertices.tobytes(), digest_size=16)
    digest.update(np.ascontiguousarray(edges).tobytes())
    key = (digest.digest(), vertices.shape, float(step))
    with _kept_lock:
        hulls = _kept.get(key)
        if hulls is not None:
            _kept.move_to_end(key)
            return hulls
    hulls = SectionHulls(vertices, edges, step)
    with _kept_lock:
        _kept[key] = hulls
        while len(_kept) > KEPT_MESHES:
            _kept.popitem(last=False)
    return hulls
