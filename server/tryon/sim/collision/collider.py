"""The body as the simulation sees it: offset surface, per-part maps, growth and arm posing.

``BodyCollider`` owns mutable copies of the arrays the collision kernels read, so that the growth phase
(each part scaled toward its axis) and the arm posing (upper arm and forearm turned rigidly about the
shoulder) can change them without touching the immutable ``Body``. Both keep the cylinder maps valid:
growth keeps every vertex's (theta, z), and a rigid turn of a part carries its frame and box along. A
change of shape within a part (``reshape``: a re-posed hand turning at the wrist) builds the maps again.
"""

from __future__ import annotations

import numpy as np

from tryon.body.types import Body
from tryon.sim.collision.kernels import (
    BodySurface, cell_max_radius, collide_points, face_boxes, grow_vertices, offset_body, part_max_radius,
    penetration_depth, vertex_parts,
)
from tryon.sim.blocks import collide_halves, depth_halves
from tryon.sim.collision.movers import Movers
from tryon.body.maps import build_part_maps, rebuild_part_maps
from tryon.geometry import face_normals, face_vertex_normals


class BodyCollider:
    """Collision state of one body for one drape.

    body: the built body; margin: m, outward offset of the collision surface (paper 3.3).
    Attributes read by the kernels: ``vertices`` (n, 3) current (grown / posed) body, ``offset`` (n, 3)
    and ``offset_normals`` (f, 3) the offset surface, and the map arrays (OBB, cylinder frames).
    """

    def __init__(self, body: Body, margin: float):
        self.body = body
        self.margin = float(margin)
        self.faces = np.ascontiguousarray(body.faces, dtype=np.int64)
        self.vertex_part = vertex_parts(self.faces, body.face_part.astype(np.int64), len(body.vertices))
        self.face_part = np.ascontiguousarray(body.face_part, dtype=np.int64)
        self._rest(body.vertices, body.vertex_normals, body.maps)
        self._built = (self.cell_base, self.cyl_shape, self.rest_rmax)  # the body as built: its cells' radii
        self.vertices = self.rest_vertices.copy()
        self.offset = np.empty_like(self.vertices)
        self.offset_normals = np.empty((len(self.faces), 3))
        self.offset_boxes = np.empty((len(self.faces), 4))
        self.corners = np.empty((len(self.vertices), 3))  # face_boxes' work space
        self.plain_boxes = np.empty((len(self.faces), 4))
        self.plain_normals = np.empty((len(self.faces), 3))
        self.scale = 1.0
        # the parts the growth scales (``set_growing``); the others keep their full size throughout
        self.growing = np.ones(len(self.cyl_shape), dtype=np.bool_)
        self._pose_vertices = self.rest_vertices
        self._pose_normals = self.rest_normals
        # the body's shape, counted up by every change (``update``), and the shape the real (un-offset)
        # surface's normals, radii and boxes were last computed for (``depth``): a drape's per-step depth
        # (``run.settle``'s motion penetration) recomputes them only while the body moves
        self.shape = 0
        self._plain_shape = -1
        self.update()

    def _rest(self, vertices: np.ndarray, normals: np.ndarray, m, changed: np.ndarray | None = None) -> None:
        """Take ``vertices`` (n, 3) m with their unit ``normals`` (n, 3) and their part maps ``m`` as the rest
        shape that posing starts from. ``changed`` (q,) int64: the only parts whose shape differs from the
        body as built (their cells' radii are measured again, the others' kept)."""
        self.rest_vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        self.rest_normals = np.ascontiguousarray(normals, dtype=np.float64)
        # map arrays that posing may change (copies), and the ones it never does
        self.rest_frames = {
            "obb_normals": m.obb_normals, "obb_offsets": m.obb_offsets, "cyl_origin": m.cyl_origin,
            "cyl_axes": m.cyl_axes, "obb_center": m.obb_center,
        }
        self.obb_normals = np.ascontiguousarray(m.obb_normals, dtype=np.float64).copy()
        self.obb_offsets = np.ascontiguousarray(m.obb_offsets, dtype=np.float64).copy()
        self.cyl_origin = np.ascontiguousarray(m.cyl_origin, dtype=np.float64).copy()
        self.cyl_axes = np.ascontiguousarray(m.cyl_axes, dtype=np.float64).copy()
        self.cyl_zrange = np.ascontiguousarray(m.cyl_zrange, dtype=np.float64)
        self.cyl_shape = np.ascontiguousarray(m.cyl_shape, dtype=np.int64)
        self.cell_base = np.ascontiguousarray(m.cell_base, dtype=np.int64)
        self.cell_start = np.ascontiguousarray(m.cell_start, dtype=np.int64)
        self.cell_faces = np.ascontiguousarray(m.cell_faces, dtype=np.int64)
        # each cell's part (a part's cells are the shape[k, 0] x shape[k, 1] from cell_base[k])
        self.cell_part = np.empty(len(self.cell_start) - 1, dtype=np.int64)
        for k, (rows, cols) in enumerate(self.cyl_shape):
            self.cell_part[self.cell_base[k]:self.cell_base[k] + rows * cols] = k
        self.rest_rmax = np.empty(len(self.cell_start) - 1)
        self.cell_rmax = np.empty(len(self.cell_start) - 1)
        self.plain_rmax = np.empty(len(self.cell_start) - 1)
        maps = (self.cyl_origin, self.cyl_axes, self.cyl_shape, self.cell_base, self.cell_start, self.cell_faces,
                self.faces, self.rest_vertices)
        if changed is None:
            cell_max_radius(*maps, self.rest_rmax)
        else:
            base, shape, rmax = self._built
            for k in np.setdiff1d(np.arange(len(shape)), changed):  # the same cells as built
                count = shape[k, 0] * shape[k, 1]
                self.rest_rmax[self.cell_base[k]:self.cell_base[k] + count] = rmax[base[k]:base[k] + count]
            part_max_radius(np.asarray(changed, dtype=np.int64), *maps, self.rest_rmax)
        # how far beyond its cell each cell's face list reaches around the offset surface, m (>= 0)
        self.cover = max(0.0, float(m.margin) - self.margin)

    def reshape(self, vertices: np.ndarray | None, changed: np.ndarray | None = None) -> None:
        """Give the body the rest shape ``vertices`` (n, 3) m (the same mesh, each part's vertices moved within
        the part: a hand turned at the wrist, an upper arm a little longer; None: the body as built), its maps
        built again for it (~10 ms at the default resolution); posing (``pose_arms``) starts from it. The offset
        surface follows at the next ``pose_arms`` or ``update``. ``changed`` (q,) int64: the parts whose shape
        differs from the body as built, if known (only their maps are built again, ~2 ms for the arms, and the
        others' cell radii are not measured again)."""
        if vertices is None:
            self._rest(self.body.vertices, self.body.vertex_normals, self.body.maps)
        else:
            if changed is None:
                maps = build_part_maps(vertices, self.faces, self.face_part, self.body.maps.part_axes,
                                       self.body.maps.margin)
            else:  # the other parts' maps are the body's as built
                maps = rebuild_part_maps(self.body.maps, vertices, self.faces, self.face_part, self.body.maps.part_axes,
                                         changed)
            self._rest(vertices, face_vertex_normals(vertices, self.faces)[1], maps, changed)
        self._pose_vertices = self.rest_vertices
        self._pose_normals = self.rest_normals
        self.shape += 1

    @property
    def vertex_normals(self) -> np.ndarray:
        """(n, 3) unit outward vertex normals of the current pose (growth does not turn them)."""
        return self._pose_normals

    # ------------------------------------------------------------------ shape changes

    def update(self) -> None:
        """Recompute the offset surface from the current posed vertices and the growth scale."""
        self.shape += 1
        part_scale = np.where(self.growing, self.scale, 1.0)
        if self.scale != 1.0:
            grow_vertices(self._pose_vertices, self.vertex_part, self.cyl_origin, self.cyl_axes, part_scale,
                          self.vertices)
        else:
            self.vertices[:] = self._pose_vertices
        offset_body(self.vertices, self._pose_normals, self.faces, self.margin, self.offset, self.offset_normals)
        face_boxes(self.offset, self.faces, self.face_part, self.vertex_part, self.cyl_origin, self.cyl_axes,
                   self.corners, self.offset_boxes)
        # Cell radii: growth scales every vertex's distance to its axis by its part's scale and the offset adds
        # at most ``margin``, and turning a part rigidly keeps its local radii, so the rest body's radii
        # bound them (computed once; the exact kernel over all (face, cell) pairs costs a few ms a call)
        np.multiply(self.rest_rmax, part_scale[self.cell_part], out=self.cell_rmax)
        self.cell_rmax += self.margin

    def reach_ratio(self) -> np.ndarray:
        """(P,) each part's farthest vertex from its axis over its median vertex's distance, in the rest shape
        (a foot's toes from the shin's axis: 4; the head and the other parts: 2 at most)."""
        k = self.vertex_part
        offset = self.rest_vertices - self.rest_frames["cyl_origin"][k]
        along = self.rest_frames["cyl_axes"][k, 2]
        radius = np.linalg.norm(offset - np.sum(offset * along, axis=1)[:, None] * along, axis=1)
        out = np.ones(len(self.cyl_shape))
        for p in range(len(out)):
            r = radius[k == p]
            if r.size and np.median(r) > 0:
                out[p] = r.max() / np.median(r)
        return out

    def set_growing(self, parts: np.ndarray) -> None:
        """Only the body parts ``parts`` (int64 indices) are scaled by the growth (``set_scale``); the others keep
        their full size. Takes effect at the next ``update``."""
        self.growing[:] = False
        self.growing[np.asarray(parts, dtype=np.int64)] = True

    def set_scale(self, scale: float, refresh: bool = True) -> None:
        """Radial scale of the growing parts (``set_growing``; every part unless told) about their axes (growth
        phase), 0 < scale <= 1. ``refresh=False`` leaves the offset surface to the caller's next change
        (``pose_arms``), which recomputes it anyway."""
        self.scale = float(scale)
        if refresh:
            self.update()

    def pose_arms(self, turns: dict[int, tuple[np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, np.ndarray]]
                  ) -> None:
        """Move body parts rigidly: ``turns[k] = (pivot (3,), R (3, 3))`` or ``(pivot, R, shift (3,))``
        moves part k's vertices to pivot + R (v - pivot) + shift, with its OBB and cylinder frame. Parts not
        named go back to rest."""
        v = self.rest_vertices.copy()
        n = self.rest_normals.copy()
        rf = self.rest_frames
        self.obb_normals[:] = rf["obb_normals"]
        self.obb_offsets[:] = rf["obb_offsets"]
        self.cyl_origin[:] = rf["cyl_origin"]
        self.cyl_axes[:] = rf["cyl_axes"]
        for k, turn in turns.items():
            pivot, rot = turn[0], turn[1]
            shift = turn[2] if len(turn) > 2 else np.zeros(3)
            sel = self.vertex_part == k
            v[sel] = pivot + (v[sel] - pivot) @ rot.T + shift
            n[sel] = n[sel] @ rot.T
            self.cyl_origin[k] = pivot + rot @ (rf["cyl_origin"][k] - pivot) + shift
            self.cyl_axes[k] = rf["cyl_axes"][k] @ rot.T
            self.obb_normals[k] = rf["obb_normals"][k] @ rot.T
            center = pivot + rot @ (rf["obb_center"][k] - pivot) + shift
            # each plane keeps its distance (half extent) to the turned centre: n' . c' + (offset - n . c)
            self.obb_offsets[k] = rf["obb_offsets"][k] - rf["obb_normals"][k] @ rf["obb_center"][k] \
                + self.obb_normals[k] @ center
        self._pose_vertices = v
        self._pose_normals = n
        self.update()

    # ------------------------------------------------------------------ queries

    def collide(self, x, x_prev, inv_mass, active, parts, lam, mu_static, mu_kinetic, contact,
                near=0.0, planes=None, hold_pinched=False, held=None, hold_depth=1e9, two=False) -> int:
        """Push points ``x`` out of the offset body in place; returns how many moved (see collide_points).
        planes: optional (has_plane (k,), plane_point (k, 3), plane_normal (k, 3)) filled with contact planes;
        hold_pinched, held, hold_depth: see collide_points (only for a body that does not move); two: half the
        points on each of two threads (``blocks.collide_halves``; the same result)."""
        if planes is None:
            planes = (np.zeros(len(x), dtype=np.bool_), np.empty((len(x), 3)), np.empty((len(x), 3)))
        surface = self._surface(self.offset, self.offset_normals, self.cell_rmax, self.offset_boxes)
        if two:
            if held is None:  # the halves' kernel takes an array: one written and not read
                held = np.zeros(len(x), dtype=np.bool_)
            return collide_halves(x, x_prev, inv_mass, active, parts, surface, lam, mu_static, mu_kinetic, contact,
                                  near, planes[0], planes[1], planes[2], hold_pinched, held, float(hold_depth))
        return collide_points(x, x_prev, inv_mass, active, parts, surface, lam, mu_static, mu_kinetic, contact, near,
                              planes[0], planes[1], planes[2], hold_pinched, held, float(hold_depth))

    def movers(self, state, parts, lam, near, reach, hold_pinched, retest_planes=False, hold_depth=1e9,
               two=False) -> Movers:
        """The within-step test's argument (``collision.movers``) for a drape's ``state`` (a ``DrapeState``)."""
        surface = self._surface(self.offset, self.offset_normals, self.cell_rmax, self.offset_boxes)
        return Movers(surface, parts, state.x_checked, state.contact, state.held, state.movers, float(reach),
                      float(lam), float(near), bool(hold_pinched), bool(retest_planes), float(hold_depth), bool(two))

    def depth(self, points: np.ndarray, parts: np.ndarray, offset: bool = False, two: bool = False) -> np.ndarray:
        """Depth (m) of each point (n, 3) inside the body (``offset=False``: the real, un-offset surface of
        the current shape), 0 outside. two: half the points on each of two threads (``blocks.depth_halves``;
        the same result)."""
        if offset:
            bv, fn, rmax, boxes = self.offset, self.offset_normals, self.cell_rmax, self.offset_boxes
        else:
            bv = self.vertices
            if self._plain_shape != self.shape:  # the body changed since the last call
                face_normals(bv, self.faces, self.plain_normals)
                if self.scale == 1.0:
                    # the body as built or with parts turned rigidly (``pose_arms``): a cell lists only its own
                    # part's faces, and a part's vertices turn with its frame, so the radii are the built
                    # body's (cell_max_radius costs 5.5 ms a call)
                    self.plain_rmax[:] = self.rest_rmax
                else:
                    cell_max_radius(self.cyl_origin, self.cyl_axes, self.cyl_shape, self.cell_base, self.cell_start,
                                    self.cell_faces, self.faces, bv, self.plain_rmax)
                face_boxes(bv, self.faces, self.face_part, self.vertex_part, self.cyl_origin, self.cyl_axes,
                           self.corners, self.plain_boxes)
                self._plain_shape = self.shape
            fn, rmax, boxes = self.plain_normals, self.plain_rmax, self.plain_boxes
        points = np.ascontiguousarray(points, dtype=np.float64)
        surface = self._surface(bv, fn, rmax, boxes)
        return depth_halves(points, parts, surface) if two else penetration_depth(points, parts, surface)

    def _surface(self, vertices, face_normals, cell_rmax, boxes) -> BodySurface:
        """The kernels' view of the offset or the real surface of the current shape."""
        return BodySurface(self.obb_normals, self.obb_offsets, self.cyl_origin, self.cyl_axes, self.cyl_zrange,
                           self.cyl_shape, self.cell_base, self.cell_start, self.cell_faces, cell_rmax, vertices,
                           self.faces, face_normals, boxes, self.cover)


def relevant_parts(maps, lo: np.ndarray, hi: np.ndarray, reach: float) -> np.ndarray:
    """Ids (q,) int64 of the parts whose OBB comes within ``reach`` (m) of the box [lo, hi] (3,) each:
    the parts a garment in that box can touch (a skirt never tests the head or the arms)."""
    corners = maps.obb_corners  # (P, 8, 3)
    keep = np.all(corners.max(axis=1) >= lo - reach, axis=1) & np.all(corners.min(axis=1) <= hi + reach, axis=1)
    keep &= np.isfinite(maps.obb_offsets).all(axis=1)
    return np.flatnonzero(keep).astype(np.int64)
