"""GarmentModel: the immutable, cached result of preparing a garment (SPEC section 3).

Everything a try-on needs and nothing it has to recompute: the full mesh (for display), the coarse
(simplified) mesh that is simulated, its springs with natural lengths and types, particle masses, and the
barycentric re-attachment of the full mesh to the coarse one.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from tryon.garment.fabric import Fabric, fabric_named, spring_stiffness
from tryon.garment.springs import BENDING, spring_model

# Version of what preparation makes of a source file; a model saved by another version is prepared again
# from its kept source (``is_current``). Raise it whenever ingest, simplification or springs change their
# output. 2: a file's connected pieces are simplified each by its own share. 3: no coarse edge of an opening longer
# than 1/8 of its loop (``simplify.MIN_LOOP_SPANS``). 4: no coarse edge under 3 % of the median (``weld.py``).
# 5: masses from the fabric's density when none is given (jersey 0.187, cotton twill 0.220 kg/m^2; was 0.15 for
# every garment), the fabric and the density recorded in the meta.
PREPARATION_VERSION = 5


@dataclass(frozen=True)
class GarmentMeta:
    """Catalogue facts about a garment (no arrays)."""

    id: str
    name: str
    category: str  # top | bottom | dress
    size: str | None
    units: str  # m | cm | mm | dm | in (what the source file was read as)
    units_guessed: bool
    simplification: float  # B = kept / original vertices
    source_sha256: str
    source_name: str
    vertices: int
    faces: int
    coarse_vertices: int
    coarse_faces: int
    springs: dict = field(default_factory=dict)  # kind name -> count
    notes: list = field(default_factory=list)  # what cleaning did, in words
    style: str | None = None  # the product this entry is one size of (a short id such as tshirt), or None
    chart: dict | None = None  # its size-chart row: {"chest" | "waist" | "hips": [min, max] cm}, or None
    fabric: str | None = None  # a name in ``fabric.FABRICS``, or None: the category's (``fabric.DEFAULT_FABRIC``)
    density: float | None = None  # kg/m^2 the masses are made of: the fabric's unless one was given; None: unknown


@dataclass(frozen=True)
class GarmentModel:
    """A prepared garment. Metres, y up. Indices int32, coordinates float64.

    vertices (n, 3): full mesh; faces (f, 3): full mesh triangles.
    coarse_index (k,): original vertex id of each coarse vertex (kept vertices are original ones).
    coarse_faces (g, 3): triangles of the coarse mesh, indices into 0..k-1.
    springs (s, 2): coarse vertex pairs; rest (s,): natural lengths (m); kind (s,) int8: 0/1/2 =
        structural/shear/bending.
    mass (k,): particle masses, kg (areal density x lumped triangle area).
    attach_face (n,), attach_bary (n, 3), attach_offset (n,): each full vertex as a barycentric point
        of a coarse face plus an offset (m) along that face's unit normal.
    """

    meta: GarmentMeta
    vertices: np.ndarray
    faces: np.ndarray
    coarse_index: np.ndarray
    coarse_faces: np.ndarray
    springs: np.ndarray
    rest: np.ndarray
    kind: np.ndarray
    mass: np.ndarray
    attach_face: np.ndarray
    attach_bary: np.ndarray
    attach_offset: np.ndarray

    ARRAYS = (
        "vertices", "faces", "coarse_index", "coarse_faces", "springs", "rest", "kind", "mass",
        "attach_face", "attach_bary", "attach_offset",
    )

    @property
    def coarse_vertices(self) -> np.ndarray:
        """(k, 3) rest positions of the coarse mesh."""
        return self.vertices[self.coarse_index]

    @property
    def fabric(self) -> Fabric:
        """The cloth it is made of: the meta's fabric, or its category's (``fabric.fabric_named``)."""
        return fabric_named(self.meta.fabric, self.meta.category)

    @cached_property
    def stiffness(self) -> np.ndarray:
        """(s,) N/m: each spring's stiffness in this garment's fabric (``fabric.spring_stiffness``)."""
        return spring_stiffness(self.kind, self.fabric)

    @property
    def edges(self) -> np.ndarray:
        """(e, 2) int64: the full mesh's edges, each once, smaller id first, sorted (what ``self_crossings`` tests;
        ``edge_faces``' own list)."""
        return self.edge_faces[1]

    @cached_property
    def coarse_edge_faces(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The coarse mesh's triangles (g, 3) int64, its edges (e, 2) int64 and the triangles on each edge (e, 2)
        int64, -1 for none (``topology.edge_faces``): what the untangling of the simulated mesh walks."""
        return _with_edge_faces(self.coarse_faces)

    @cached_property
    def edge_faces(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``coarse_edge_faces`` of the full (shown) mesh."""
        return _with_edge_faces(self.faces)

    @cached_property
    def display_springs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The full mesh's structural and shear springs (``springs.spring_model`` without bending): pairs
        (m, 2) int64, natural lengths (m,) m, kinds (m,) int8. What keeps the displayed mesh's triangles
        within the cloth's stretch limits where it follows the coarse one (``expand``), whose triangles,
        free to shear and buckle between their springs, stretch the full triangles on them by up to 60 %.
        Computed once per model (10-20 ms for 3,000-5,000 vertices)."""

        pairs, rest, kind = spring_model(self.vertices, self.faces)
        keep = kind != BENDING
        return pairs[keep].astype(np.int64), rest[keep], kind[keep]

    @cached_property
    def coarse_loops(self) -> list[np.ndarray]:
        """The coarse mesh's openings (``topology.boundary_loops``): one int64 array of coarse vertex ids per
        boundary loop. Computed once per model (about 1 ms; the alignment, the arm plan and the sleeve
        metric all read them)."""
        from tryon.garment.topology import boundary_loops

        return boundary_loops(self.coarse_faces, len(self.coarse_index))

    @cached_property
    def loops(self) -> list[np.ndarray]:
        """The full (shown) mesh's openings: one int64 array of vertex ids per boundary loop, as
        ``coarse_loops``. Computed once per model (a few ms for 3,000-5,000 vertices)."""
        from tryon.garment.topology import boundary_loops

        return boundary_loops(self.faces, len(self.vertices))

    def expand(self, coarse_positions: np.ndarray) -> np.ndarray:
        """Full-mesh positions (n, 3) from coarse positions (k, 3) via the re-attachment."""
        tri = coarse_positions[self.coarse_faces[self.attach_face]]  # (n, 3, 3)
        p = np.einsum("nj,njk->nk", self.attach_bary, tri)
        nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        length = np.linalg.norm(nrm, axis=1, keepdims=True)
        nrm /= np.where(length > 0, length, 1.0)
        return p + nrm * self.attach_offset[:, None]

    def resized(self, coarse_shape: np.ndarray) -> "GarmentModel":
        """This garment with ``coarse_shape`` (k, 3) m as its coarse mesh's natural shape: each spring's
        natural length scaled by its length there over its length at rest, the full mesh following the
        coarse one (its displacement through the re-attachment, ``expand``). For a garment sized to a body
        (guessed units); masses, topology and re-attachment are kept."""
        shape = np.asarray(coarse_shape, dtype=np.float64)
        before, after = self.coarse_vertices, shape
        a, b = self.springs[:, 0], self.springs[:, 1]
        ratio = np.linalg.norm(after[a] - after[b], axis=1) / np.maximum(
            np.linalg.norm(before[a] - before[b], axis=1), 1e-12)
        vertices = self.vertices + (self.expand(shape) - self.expand(before))
        vertices[self.coarse_index] = shape
        return replace(self, vertices=vertices, rest=self.rest * ratio)

    def save(self, directory: Path) -> None:
        """Write ``model.npz``, ``meta.json`` and ``prepared.json`` (the preparation version) into
        ``directory`` (which must exist)."""
        np.savez(directory / "model.npz", **{k: getattr(self, k) for k in self.ARRAYS})
        (directory / "prepared.json").write_text(json.dumps({"version": PREPARATION_VERSION}))
        (directory / "meta.json").write_text(json.dumps(asdict(self.meta), indent=1))

    @staticmethod
    def is_current(directory: Path) -> bool:
        """Whether ``directory`` holds a complete model saved by this ``PREPARATION_VERSION``."""
        try:
            version = json.loads((directory / "prepared.json").read_text())["version"]
        except (OSError, ValueError, KeyError, TypeError):
            return False
        return version == PREPARATION_VERSION and (directory / "meta.json").exists()

    @classmethod
    def load(cls, directory: Path) -> "GarmentModel":
        meta = GarmentMeta(**json.loads((directory / "meta.json").read_text()))
        with np.load(directory / "model.npz") as z:
            arrays = {k: z[k] for k in cls.ARRAYS}
        return cls(meta=meta, **arrays)


def _with_edge_faces(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(faces (f, 3) int64 contiguous, *``topology.edge_faces(faces)``)."""
    from tryon.garment.topology import edge_faces

    faces = np.ascontiguousarray(faces, dtype=np.int64)
    return (faces, *edge_faces(faces))
