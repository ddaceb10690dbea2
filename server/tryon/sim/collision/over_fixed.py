"""A mesh kept off fixed meshes under it: an outfit's outer shown mesh off the shown meshes of the garments
under it, which are finished and hold still (issue 29).

Both ways, as in the simulation's layer collision (``cloth.push_outside_layer``): the outer mesh's points go
``gap`` outside the inner surface, and the inner points that lie outside the outer surface push the outer
triangle over them out (the point-triangle constraint with the inner side's inverse masses 0). Each round moves
a point at most ``max_push`` (a hem over a flared skirt pushed along its tilted normals in one jump grew
spikes); the caller's stretch passes between calls spread the pushes to the neighbours.

Skip what is not needed: the inner triangles' grid is built once; the first round of a call tests every point
within reach, the later rounds only the outer points that moved in the round before and the inner points within
reach of an outer triangle that moved. Testing every point in every round gives the same layer-penetrating
count on the outfits bench: a push moves the outer mesh away from the inner one, except where the two
meshes' outward sides disagree (an armpit, where the nearest body axis changes), and there it is a point
that moved.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from tryon.geometry import stack_meshes
from tryon.sim.collision.cloth import build_tri_grid, overlap, push_layer, signed_face_normals


@njit(cache=True, nogil=True)
def in_filled_cells(points, grid_lo, grid_cell, grid_shape, cell_start):
    """(k,) bool: which of ``points`` (k, 3) m lie in a cell of a ``TriGrid`` that lists a triangle (within the
    grid's pad of one)."""
    out = np.zeros(points.shape[0], dtype=np.bool_)
    for i in range(points.shape[0]):
        inside = True
        c = 0
        for a in range(3):
            k = int((points[i, a] - grid_lo[a]) / grid_cell)
            if points[i, a] < grid_lo[a] or k >= grid_shape[a]:
                inside = False
                break
            c = c * grid_shape[a] + k
        if inside:
            out[i] = cell_start[c + 1] > cell_start[c]
    return out


class OverFixed:
    """Keeps an outer mesh (triangles ``faces`` (f, 3) int64) ``gap`` m outside the fixed meshes ``under``
    ((vertices (n_i, 3) m, triangles (f_i, 3) int64, outward sides (f_i,) +-1), ``collision.cloth.face_sides``).
    ``reach`` m: how far from a surface a point is looked at; ``cell`` m: the grids' cell."""

    def __init__(self, under: list[tuple[np.ndarray, np.ndarray, np.ndarray]], faces: np.ndarray, gap: float,
                 max_push: float, rounds: int, reach: float, cell: float):
        vertices, tris = stack_meshes([(v, f) for v, f, _ in under])
        self.x = np.ascontiguousarray(vertices, dtype=np.float64)
        self.faces = np.ascontiguousarray(tris, dtype=np.int64)
        self.normals = signed_face_normals(self.x, self.faces, np.concatenate([s for _, _, s in under]))
        self.grid = build_tri_grid(self.x, self.faces, cell, reach)
        self.outer_faces = np.ascontiguousarray(faces, dtype=np.int64)
        self.gap, self.max_push, self.rounds, self.reach, self.cell = gap, max_push, rounds, reach, cell
        self._fixed = np.zeros(len(self.x))

    def push(self, x: np.ndarray, x_prev: np.ndarray, sides: np.ndarray, moved: np.ndarray | None = None) -> int:
        """Push the outer mesh ``x`` (n, 3) m in place (``x_prev`` moved with it), its triangles turned outward
        by ``sides`` (f,) +-1; up to ``rounds`` rounds, until none pushes. ``moved`` (n,) bool: the only outer
        points that moved since the mesh was last pushed (a round of its untangling): the first round then tests
        what a later round would. Returns how many pushes there were."""
        ones = np.ones(len(x))
        outer_active = overlap(x, self.x, self.faces, self.reach)[0]
        inner_active = overlap(self.x, x, self.outer_faces, self.reach)[0]
        if moved is not None:
            if not moved.any():
                return 0
            outer_active &= moved
            inner_active &= self._near(x, moved)
        inner_prev = self.x.copy()  # never moved: the inner side's inverse masses are 0
        total = 0
        for _ in range(self.rounds):
            before = x.copy()
            total += push_layer(x, x_prev, ones, outer_active, self.x, inner_prev, self._fixed, self.faces,
                                self.normals, self.grid, self.gap, self.reach, max_push=self.max_push)
            if inner_active.any():
                close = overlap(self.x[inner_active], x, self.outer_faces, self.reach)[1]
                tris = np.ascontiguousarray(self.outer_faces[close])
                normals = signed_face_normals(x, tris, -sides[close])
                grid = build_tri_grid(x, tris, self.cell, self.reach)
                total += push_layer(self.x, inner_prev, self._fixed, inner_active, x, x_prev, ones, tris, normals,
                                    grid, self.gap, self.reach, max_push=self.max_push)
            moved = np.any(x != before, axis=1)
            if not moved.any():
                break
            # next round: the outer points that moved in this one (pushed, or a corner of a triangle an inner point
            # pushed), and the inner points near a triangle that moved
            outer_active = moved
            inner_active &= self._near(x, moved)
        return total

    def _near(self, x: np.ndarray, moved: np.ndarray) -> np.ndarray:
        """(n_inner,) bool: the inner points within reach of an outer triangle with a corner in ``moved`` (n,)."""
        near = build_tri_grid(x, np.ascontiguousarray(self.outer_faces[moved[self.outer_faces].any(axis=1)]),
                              self.cell, self.reach)
        return in_filled_cells(self.x, near.lo, near.cell, near.shape, near.cell_start)
