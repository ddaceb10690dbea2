"""The separate pieces of a garment file and the kind each is aligned as (issue 5).

A file may hold several garments at once (a MakeHuman outfit: a shirt and trousers, a blouse and a
skirt, as separate connected components). Aligned as one rigid "top", the trousers go wherever the shirt
puts them (the outfit was modelled on another body, with another distance from shoulders to waist), so
their legs miss the body's legs. Each piece is therefore aligned by its own kind:

- a piece whose top hangs below the middle of the highest piece (its top is at a waist) is a bottom:
  its waistband goes to the body's waist, its legs over the body's legs;
- every other piece (the one over the shoulders, and anything beside it, such as a collar or a belt
  modelled with it) is aligned with the highest piece, by the garment's category.

A garment catalogued as a bottom is one bottom, whatever its pieces. Pieces are the connected components
of the coarse mesh (simplification never joins two components), found when needed: a few hundred
microseconds on a 700-vertex coarse mesh, cheaper than a new cached model format.
"""

from __future__ import annotations

import numpy as np

from tryon.garment.topology import vertex_pieces

# A piece is a bottom when its highest point is below this fraction of the highest piece's height (from
# the highest piece's lowest point). 0.5: a waistband hangs at most at the middle of a shirt; the
# MakeHuman trousers and skirt tops are at 0.05-0.25 of their shirt's or blouse's height, and a collar,
# belt or sleeve piece modelled beside a top reaches far higher.
BOTTOM_TOP_FRACTION = 0.5


def piece_labels(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """(n_vertices,) int64 connected-component label of each vertex over the triangles ``faces`` (f, 3);
    a vertex in no face is a piece of its own."""
    return vertex_pieces(faces, n_vertices)[1]


def bottom_mask(points: np.ndarray, faces: np.ndarray, category: str) -> np.ndarray:
    """(k,) bool: which of the garment's points (k, 3), metres, y up, belong to a piece aligned as a bottom
    (see the module doc). ``faces`` (f, 3) index ``points``; ``category`` is top | bottom | dress."""
    k = len(points)
    if category == "bottom":
        return np.ones(k, dtype=np.bool_)
    label = piece_labels(faces, k)
    count = int(label.max()) + 1 if k else 0
    if count < 2:
        return np.zeros(k, dtype=np.bool_)
    y = points[:, 1]
    top_y = np.full(count, -np.inf)
    low_y = np.full(count, np.inf)
    np.maximum.at(top_y, label, y)
    np.minimum.at(low_y, label, y)
    highest = int(np.argmax(top_y))
    cut = low_y[highest] + BOTTOM_TOP_FRACTION * (top_y[highest] - low_y[highest])
    return (top_y < cut)[label]
