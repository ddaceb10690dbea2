"""Ease: how much room a draped garment leaves around the body, girth by girth, measured with a tape.

At each body girth the garment covers (``GIRTHS_COVERED``: the chest for tops and dresses, the waist and
hips for bottoms and dresses) the horizontal plane at the body's level of that girth (``Body.levels``) cuts
the draped garment's shown mesh. At the waist and hips, the closed rings of cloth that go around the torso
count (not a trouser leg's or a sleeve's ring around a limb); at the chest, the cloth within the torso's
breadth (``chest_cut``: a tape passes under the arms). Then:

- ``garment_cm``: the tape girth of the draped garment, the perimeter of the convex hull of that cut;
- ``body_cm``: the body's tape girth at the same level, measured the same way on the body's torso
  (``tryon.body.measure``: equal to the body's achieved girth at its own level);
- ``ease_cm = garment_cm - body_cm``: what a tailor calls ease. Cloth lying on the skin still measures about
  2 pi (collision margin + contact offset) = 2.8 cm over the body: the simulated cloth lies on the body
  offset by that margin (``SimSettings.collision_margin``), as real cloth has a thickness;
- ``cloth_cm``: the tape girth the ring would have unstretched: ``garment_cm`` over the ring's stretch along
  the cut (its segments' draped length over the same material segments' length on the garment at rest).
  ``cloth_cm - body_cm`` is the room the cloth itself leaves: negative where the garment is short.

A bottom whose band sits lower than the body's waist (trousers on the hips)
is measured at its band, ``BAND_BELOW_TOP`` under the lowest point of its top rim; the body there too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from tryon.body.measure import horizontal_girth, hull_perimeter, mesh_edges
from tryon.body.types import Body

# The body girths each category covers (``Body.levels`` names).
GIRTHS_COVERED = {"top": ("chest",), "bottom": ("waist", "hips"), "dress": ("chest", "waist", "hips")}
# m: a bottom's band is measured this far under the lowest point of its top rim (a waistband is 3-4 cm high;
# 1 cm under its edge cuts through it all the way round, not through the rolled rim).
BAND_BELOW_TOP = 0.01
# m: a bottom whose band is further than this under a girth's level does not cover it (it slid off; its
# ease at that girth is not measured).
LEVEL_REACH = 0.10
# m: a body part's centre at a height is the mean of its vertices this close to that height.
CENTRE_BAND = 0.02
# Angular sectors around a bottom's axis in which its top rim's height is taken.
RIM_SECTORS = 36


@dataclass(frozen=True)
class Girth:
    """One girth's ease. level_m: height of the cut, m; body_cm, garment_cm, cloth_cm: tape girths of the
    body, of the draped garment, and of the garment's ring unstretched, cm."""

    name: str
    level_m: float
    body_cm: float
    garment_cm: float
    cloth_cm: float

    @property
    def ease_cm(self) -> float:
        """Tape ease: the draped garment's girth minus the body's, cm."""
        return self.garment_cm - self.body_cm

    @property
    def cloth_ease_cm(self) -> float:
        """The cloth's own girth there minus the body's, cm: negative = the garment is that much short."""
        return self.cloth_cm - self.body_cm


def section_segments(vertices: np.ndarray, faces: np.ndarray, y: float) -> tuple[np.ndarray, np.ndarray]:
    """The cut of the triangles ``faces`` (f, 3) of ``vertices`` (n, 3) by the plane at height ``y`` (m):
    its segments (s, 2, 3) m, one per triangle the plane crosses, and for each segment end the edge it lies
    on with its parameter: (s, 2, 3) = (vertex i, vertex j, t), the point being v_i + t (v_j - v_i).
    A vertex exactly on the plane counts as below it."""
    d = vertices[:, 1] - y
    above = d[faces] > 0  # (f, 3)
    crossing = above.any(axis=1) & ~above.all(axis=1)
    f = faces[crossing]
    a = f  # edge k runs from corner k to corner k + 1
    b = f[:, [1, 2, 0]]
    cut = above[crossing] != above[crossing][:, [1, 2, 0]]  # (s, 3): the two edges crossing the plane
    ia, ib = a[cut].reshape(-1, 2), b[cut].reshape(-1, 2)
    t = d[ia] / (d[ia] - d[ib])
    points = vertices[ia] + t[..., None] * (vertices[ib] - vertices[ia])
    return points, np.stack([ia, ib, t], axis=-1)


def body_girth(body: Body, y: float) -> float:
    """The body's tape girth (m) at height ``y``: its torso's horizontal section, as ``build_body``
    measures its chest, waist and hips."""
    torso = body.face_part == body.parts.index("torso")
    return horizontal_girth(body.vertices, mesh_edges(body.faces[torso]), y)


def _centre(body: Body, parts: tuple[str, ...], y: float) -> np.ndarray | None:
    """(x, z) m: the mean of the vertices of body ``parts`` within ``CENTRE_BAND`` of height ``y``, or None."""
    sel = np.isin(np.array(body.parts)[body.face_part], parts)
    ids = np.unique(body.faces[sel])
    near = ids[np.abs(body.vertices[ids, 1] - y) < CENTRE_BAND]
    return body.vertices[near][:, [0, 2]].mean(axis=0) if len(near) else None


def _encloses(segments: np.ndarray, piece: np.ndarray, n_pieces: int, point: np.ndarray) -> np.ndarray:
    """(n_pieces,) bool: which pieces of a cut (segments (s, 2, 3), piece (s,)) go around ``point`` (x, z):
    a ray from it towards +x crosses them an odd number of times."""
    a, b = segments[:, 0], segments[:, 1]
    da, db = a[:, 2] - point[1], b[:, 2] - point[1]
    straddle = (da > 0) != (db > 0)
    x_cross = a[:, 0] + (b[:, 0] - a[:, 0]) * da / np.where(straddle, da - db, 1.0)
    crosses = straddle & (x_cross > point[0])
    return np.bincount(piece, weights=crosses, minlength=n_pieces) % 2 == 1


def torso_ring(body: Body, vertices: np.ndarray, faces: np.ndarray, y: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The ring of cloth the plane at height ``y`` cuts around the torso: ``section_segments`` joined into
    pieces (segments meet on the mesh edges they cut), the closed ones going around the torso's centre at
    that height. Returns its segments and their edge parameters; None when no closed piece goes around the
    torso."""
    segments, where = section_segments(vertices, faces, y)
    centre = _centre(body, ("torso",), y)
    if len(segments) < 3 or centre is None:
        return None
    ends = np.sort(where[..., :2].astype(np.int64), axis=-1)  # (s, 2, 2): the mesh edge of each end
    _, node = np.unique((ends[..., 0] * len(vertices) + ends[..., 1]).ravel(), return_inverse=True)
    node = node.reshape(-1, 2)
    n_nodes = int(node.max()) + 1
    graph = coo_matrix((np.ones(len(node)), (node[:, 0], node[:, 1])), shape=(n_nodes, n_nodes))
    n_pieces, label = connected_components(graph, directed=False)
    piece = label[node[:, 0]]
    # closed: every crossing point of the piece ends two of its segments (an open chain ends at an opening)
    degree = np.bincount(node.ravel(), minlength=n_nodes)
    open_piece = np.zeros(n_pieces, dtype=bool)
    open_piece[label[degree != 2]] = True
    around = _encloses(segments, piece, n_pieces, centre) & ~open_piece
    if not around.any():
        return None
    keep = around[piece]
    return segments[keep], where[keep]


def chest_cut(body: Body, vertices: np.ndarray, faces: np.ndarray, y: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The cut at height ``y`` where a tape around the chest lies: the segments whose middle is within the
    torso's breadth there (the front and the back; the tape passes under the arms, straight across the
    armholes: the cloth of the sleeves and armholes at the torso's sides is left out). Returns the segments
    and their edge parameters (``section_segments``), or None if the torso is not cut there.

    Why not the whole ring: at the chest level of the service's body the catalogue's tops are cut through
    their armholes, and their sleeves' roots hang there at the torso's sides; with them, S, M and L measured
    the same 11-12 cm of ease on one body. Within the torso's breadth, 6.5, 7.8 and 8.8 cm. The window also
    clips the sides of a top much wider than the body (its ease is then underestimated: a T-shirt two sizes
    over the chart's measures 18-25 cm, where its pattern gives 24)."""
    torso = np.unique(body.faces[body.face_part == body.parts.index("torso")])
    near = torso[np.abs(body.vertices[torso, 1] - y) < CENTRE_BAND / 2]
    segments, where = section_segments(vertices, faces, y)
    if len(near) == 0 or len(segments) == 0:
        return None
    lo, hi = body.vertices[near, 0].min(), body.vertices[near, 0].max()
    middle = segments[:, :, 0].mean(axis=1)
    keep = (middle >= lo) & (middle <= hi)
    return (segments[keep], where[keep]) if keep.sum() >= 3 else None


def girth_at(body: Body, name: str, level: float, vertices: np.ndarray, faces: np.ndarray,
             rest_vertices: np.ndarray) -> Girth | None:
    """The ``Girth`` called ``name`` at height ``level`` (m) of the draped garment ``vertices`` (n, 3) with
    ``faces``, its rest shape ``rest_vertices`` (n, 3); None where the plane cuts no closed ring of cloth
    around the torso. The chest: the cloth within the torso's breadth (``chest_cut``)."""
    if name == "chest":
        cut = chest_cut(body, vertices, faces, level)
        if cut is None:
            return None
        segments, where = cut
    else:
        ring = torso_ring(body, vertices, faces, level)
        if ring is None:
            return None
        segments, where = ring
    i, j, t = where[..., 0].astype(np.int64), where[..., 1].astype(np.int64), where[..., 2]
    rest = rest_vertices[i] + t[..., None] * (rest_vertices[j] - rest_vertices[i])  # (s, 2, 3)
    stretch = (np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1).sum()
               / max(float(np.linalg.norm(rest[:, 1] - rest[:, 0], axis=1).sum()), 1e-12))
    tape = hull_perimeter(segments.reshape(-1, 3)[:, [0, 2]])
    return Girth(name, float(level), 100.0 * body_girth(body, level), 100.0 * tape, 100.0 * tape / stretch)


def rim_low(vertices: np.ndarray, sectors: int = RIM_SECTORS) -> float:
    """Height (m) of the lowest point of a garment's top rim: the highest vertex in each angular sector
    around its vertical axis (through the centre of its top 10 cm), the lowest of those."""
    top = vertices[vertices[:, 1] > vertices[:, 1].max() - 0.10]
    c = top[:, [0, 2]].mean(axis=0)
    angle = np.arctan2(vertices[:, 2] - c[1], vertices[:, 0] - c[0])
    sector = np.minimum(((angle + np.pi) / (2 * np.pi) * sectors).astype(np.int64), sectors - 1)
    highest = np.full(sectors, -np.inf)
    np.maximum.at(highest, sector, vertices[:, 1])
    return float(highest[np.isfinite(highest)].min())


def measure_ease(body: Body, vertices: np.ndarray, faces: np.ndarray, rest_vertices: np.ndarray,
                 category: str) -> dict[str, Girth | None]:
    """Each girth the garment's ``category`` covers (``GIRTHS_COVERED``): its ``Girth`` on the draped garment
    ``vertices`` (n, 3) m with ``faces`` (f, 3) and rest shape ``rest_vertices`` (n, 3), or None where the
    garment does not cover the body there. See the module doc."""
    out: dict[str, Girth | None] = {}
    band = rim_low(vertices) - BAND_BELOW_TOP if category == "bottom" else np.inf
    for name in GIRTHS_COVERED.get(category, ()):
        level = float(body.levels[name])
        if band < level:  # a bottom sitting lower: measured at its band
            if level - band > LEVEL_REACH:
                out[name] = None
                continue
            level = band
        girth = girth_at(body, name, level, vertices, faces, rest_vertices)
        out[name] = girth
    return out
