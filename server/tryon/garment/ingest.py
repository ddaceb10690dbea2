"""Load any garment mesh file into a clean triangle mesh in metres, y up (SPEC section 3).

``load_garment(data, filename, units, max_faces) -> CleanMesh``: read with trimesh, weld, split quads,
drop degenerate/duplicate faces and specks, orient y up, convert to metres. Everything refused raises
``GarmentError`` with a reason a user can act on.
"""

from __future__ import annotations

import io
import re
import warnings
from dataclasses import dataclass, field
from pathlib import PurePosixPath, PureWindowsPath

import numpy as np
import scipy.sparse
import scipy.sparse.csgraph
import trimesh

from tryon.garment.topology import vertex_pieces

# Scale from a file unit to metres.
UNIT_SCALE = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "in": 0.0254}
UNITS = (*UNIT_SCALE, "auto")
# Order in which "auto" prefers units when several give a wearable size (metric first; cm vs in is the
# only pair whose ratio, 2.54, lets both land in the wearable range).
AUTO_PREFERENCE = ("m", "cm", "mm", "dm", "in")
# A worn garment is 0.2-1.6 m tall (a mini skirt to a floor-length dress) and at least 0.28 m wide
# (it goes around an adult's hips or chest); at most 2.2 m wide (sleeves of a T-pose top).
WEARABLE_HEIGHT_M = (0.2, 1.6)
WEARABLE_WIDTH_M = (0.28, 2.2)
# Declared units that make the garment shorter than 5 cm or taller than 5 m are surely wrong.
SANE_SIZE_M = (0.05, 5.0)

FORMATS = ("obj", "glb", "gltf", "ply", "stl", "off")
REFUSED_FORMATS = {
    "3ds": "3DS files are not supported (there is no maintained 3DS reader for Python): export the "
    "garment as OBJ or GLB from your 3D tool",
    "fbx": "FBX files are not supported: export the garment as OBJ or GLB",
    "blend": "Blender files are not supported: export the garment as OBJ or GLB (File > Export)",
    "dae": "COLLADA files are not supported: export the garment as OBJ or GLB",
}

# A component is kept if its area is at least this fraction of the largest component's area: drops
# specks (buttons, stray triangles) but keeps a second garment piece (trousers next to a top).
MIN_COMPONENT_AREA_FRACTION = 0.02
# Faces whose area is below this fraction of the mean face area are degenerate (slivers with no area).
DEGENERATE_AREA_FRACTION = 1e-6
# More than this fraction of the vertices used by no face means faces were cut off (a truncated file);
# exporters leave a few stray vertices at most.
MAX_UNUSED_VERTEX_FRACTION = 0.2
# The largest opening's plane normal within 32 degrees of an axis (cos 0.85) makes that axis "up";
# the opening counts as a plane if its thickness is under 40% of its second extent.
LOOP_AXIS_COS = 0.85
LOOP_FLATNESS = 0.4
# A panel is flat when its thickness (smallest principal extent) is under 1% of its size.
FLAT_PANEL_RATIO = 0.01


class GarmentError(ValueError):
    """A garment file was refused; ``str(error)`` is a reason a user can act on.

    ``status`` is the HTTP status the service answers with: 422 (a file it cannot use), 415 (a file
    type it does not read), 413 (too large), 400 (a bad file name)."""

    def __init__(self, message: str, status: int = 422):
        super().__init__(message)
        self.status = status


@dataclass
class CleanMesh:
    """A loaded, cleaned garment: ``vertices (n, 3)`` float64 metres y up, ``faces (f, 3)`` int32."""

    vertices: np.ndarray
    faces: np.ndarray
    units: str
    units_guessed: bool
    notes: list[str] = field(default_factory=list)


def file_extension(filename: str) -> str:
    """Lower-case extension of a bare file name; refuses paths and unknown formats."""
    if not filename or filename != PurePosixPath(filename).name or filename != PureWindowsPath(filename).name:
        raise GarmentError(f"file name {filename!r} must be a bare name without a directory part", 400)
    if filename in (".", "..") or "\x00" in filename:
        raise GarmentError(f"file name {filename!r} is not a valid file name", 400)
    ext = PurePosixPath(filename).suffix.lower().lstrip(".")
    if ext in REFUSED_FORMATS:
        raise GarmentError(REFUSED_FORMATS[ext], 415)
    if ext not in FORMATS:
        raise GarmentError(
            f"unknown file type {('.' + ext) if ext else '(no extension)'!r}: use one of "
            + ", ".join("." + f for f in FORMATS),
            415,
        )
    return ext


def load_garment(data: bytes, filename: str, units: str = "auto", max_faces: int = 400_000) -> CleanMesh:
    """Read ``data`` (the bytes of a file called ``filename``) into a clean mesh in metres, y up."""
    ext = file_extension(filename)
    if units not in UNITS:
        raise GarmentError(f"units must be one of {', '.join(UNITS)}, not {units!r}")
    if not data:
        raise GarmentError("the file is empty")
    notes: list[str] = []
    if ext == "obj":
        _refuse_truncated_obj(data)
    vertices, faces = _read(data, ext, max_faces)
    unused = _unused_fraction(data, ext, vertices, faces)
    if unused > MAX_UNUSED_VERTEX_FRACTION:
        raise GarmentError(
            f"{unused:.0%} of the vertices belong to no face: the file looks truncated (faces missing)"
        )
    stitches = _count_lines(data, b"stitch") if ext == "obj" else 0
    if ext == "obj" and (stitches or b"\nseam " in data):
        notes.append("ignored non-standard OBJ 'stitch'/'seam' lines")
    vertices, faces = _clean(vertices, faces, notes)
    _refuse_sewing_pattern(vertices, faces, stitches)
    vertices, faces = _largest_components(vertices, faces, notes)
    vertices = _orient_y_up(vertices, faces, notes)
    vertices, units, guessed = _to_metres(vertices, units, notes)
    return CleanMesh(vertices=vertices, faces=faces, units=units, units_guessed=guessed, notes=notes)


# --- reading --------------------------------------------------------------------------------------


def _read(data: bytes, ext: str, max_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """Parse with trimesh (no processing), weld UV/normal seams, return raw float64/int64 arrays."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            loaded = trimesh.load(io.BytesIO(data), file_type=ext, process=False)
    except Exception as exc:  # trimesh raises many types for broken files
        if ext == "gltf" and b'"uri"' in data and b'"data:' not in data:
            raise GarmentError(
                "this .gltf refers to separate buffer files, which were not uploaded: export a single .glb "
                "(or a .gltf with embedded buffers)"
            ) from exc
        raise GarmentError(
            f"could not read the file as {ext.upper()}: it is truncated or not a mesh ({_short(exc)})"
        ) from exc
    if isinstance(loaded, trimesh.Scene):
        geoms = [g for g in loaded.dump(concatenate=False) if isinstance(g, trimesh.Trimesh)] if loaded.geometry else []
        if not geoms:
            raise GarmentError("the file has no triangle or quad faces (no mesh in the scene)")
        mesh = trimesh.util.concatenate(geoms) if len(geoms) > 1 else geoms[0]
    elif isinstance(loaded, trimesh.Trimesh):
        mesh = loaded
    elif isinstance(loaded, trimesh.PointCloud):
        raise GarmentError("the file is a point cloud (vertices without faces): a garment needs faces")
    else:
        raise GarmentError(f"the file holds a {type(loaded).__name__}, not a surface mesh with faces")
    faces = np.asarray(mesh.faces)
    if faces.size == 0:
        raise GarmentError("the file has no faces (a point cloud or empty mesh): a garment needs faces")
    if len(faces) > max_faces:
        raise GarmentError(f"the mesh has {len(faces):,} faces, more than the limit of {max_faces:,}", 413)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if not np.isfinite(vertices).all():
        raise GarmentError("the file has non-finite vertex coordinates (NaN or infinity)")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise GarmentError("the file has faces that refer to vertices that do not exist")
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    # trimesh keeps vertices apart at UV and normal seams unless told: weld by position only.
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)


def _unused_fraction(data: bytes, ext: str, vertices: np.ndarray, faces: np.ndarray) -> float:
    """Fraction of the file's distinct vertex positions that no face uses. trimesh's OBJ reader drops
    unused vertices, so for OBJ the ``v`` lines are counted from the text."""
    used = len(np.unique(vertices[np.unique(faces)], axis=0))
    if ext != "obj":
        return 1.0 - used / max(len(np.unique(vertices, axis=0)), 1)
    rows = re.findall(rb"(?m)^v[ \t]+(\S+)[ \t]+(\S+)[ \t]+(\S+)", data)
    try:
        total = len(np.unique(np.array(rows, dtype=np.float64), axis=0)) if rows else used
    except ValueError:
        return 0.0  # unparsable numbers: trimesh read them somehow; do not guess
    return 1.0 - used / max(total, used, 1)


def _refuse_truncated_obj(data: bytes) -> None:
    """An OBJ cut off in the middle of a ``v`` or ``f`` line is truncated."""
    tail = data.rstrip(b"\r\n\t ")
    if tail != data.rstrip(b"\t "):  # ends with a newline: nothing visibly cut
        return
    last = tail.rsplit(b"\n", 1)[-1].split()
    if (last[:1] == [b"v"] and len(last) < 4) or (last[:1] == [b"f"] and len(last) < 4):
        raise GarmentError("the file ends in the middle of a line: it is truncated")


def _short(exc: Exception) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return text[:120]


# --- cleaning -------------------------------------------------------------------------------------


def _clean(vertices: np.ndarray, faces: np.ndarray, notes: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Drop degenerate and duplicate faces and unreferenced vertices."""
    n_in = len(faces)
    repeated = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 0] == faces[:, 2])
    tri = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    mean_area = area[~repeated].mean() if (~repeated).any() else 0.0
    degenerate = repeated | (area <= DEGENERATE_AREA_FRACTION * mean_area)
    faces = faces[~degenerate]
    if degenerate.any():
        notes.append(f"dropped {int(degenerate.sum())} degenerate faces")
    if len(faces) == 0:
        raise GarmentError("every face of the mesh is degenerate (zero area): nothing to simulate")
    _, first = np.unique(np.sort(faces, axis=1), axis=0, return_index=True)
    if len(first) < len(faces):
        notes.append(f"dropped {len(faces) - len(first)} duplicate faces")
        faces = faces[np.sort(first)]
    used = np.unique(faces)
    if len(used) < len(vertices):
        remap = np.full(len(vertices), -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
        vertices, faces = vertices[used], remap[faces]
    if len(faces) < n_in and not notes:
        notes.append(f"dropped {n_in - len(faces)} faces")
    return vertices, faces.astype(np.int32)


def _components(n_vertices: int, faces: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components over shared vertices: (count, label per face)."""
    count, vertex_label = vertex_pieces(faces, n_vertices)
    return count, vertex_label[faces[:, 0]]


def _face_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    tri = vertices[faces]
    return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)


def _count_lines(data: bytes, keyword: bytes) -> int:
    """How many lines of an OBJ file start with ``keyword`` followed by a space."""
    return data.count(b"\n" + keyword + b" ") + int(data.startswith(keyword + b" "))


def _refuse_sewing_pattern(vertices: np.ndarray, faces: np.ndarray, stitches: int = 0) -> None:
    """Refuse a file of flat, unsewn pattern panels: it is not a garment that can be worn yet. ``stitches``:
    the file's non-standard ``stitch`` lines (Codim-IPC's sewing instructions), named in the refusal: the
    service does not sew panels (a sewn drape would pull each stitch's ends together around the body)."""
    count, label = _components(len(vertices), faces)
    if count < 2:
        return
    area = np.bincount(label, weights=_face_areas(vertices, faces), minlength=count)
    big = np.flatnonzero(area >= MIN_COMPONENT_AREA_FRACTION * area.max())
    if len(big) < 2:
        return
    flat_area = 0.0
    for c in big:  # a handful of components, not a loop over faces
        pts = vertices[np.unique(faces[label == c])]
        spread = np.linalg.svd(pts - pts.mean(axis=0), compute_uv=False)
        if spread[2] <= FLAT_PANEL_RATIO * spread[0]:
            flat_area += area[c]
    if flat_area >= 0.9 * area[big].sum():
        sewing = (f"; its {stitches} 'stitch' lines are not read: flat patterns with stitch lines are not "
                  "supported" if stitches else "")
        raise GarmentError(
            f"flat sewing pattern panels, not a sewn garment ({len(big)} flat pieces{sewing}): sew the "
            "panels into a 3D garment in a cloth tool and export that"
        )


def _largest_components(vertices: np.ndarray, faces: np.ndarray, notes: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Keep the pieces of real size (area >= 2% of the largest); drop specks."""
    count, label = _components(len(vertices), faces)
    if count == 1:
        return vertices, faces
    area = np.bincount(label, weights=_face_areas(vertices, faces), minlength=count)
    keep = area >= MIN_COMPONENT_AREA_FRACTION * area.max()
    kept = int(keep.sum())
    if kept < count:
        notes.append(f"dropped {count - kept} small loose pieces ({int((~keep[label]).sum())} faces)")
    if kept > 1:
        notes.append(f"kept {kept} separate pieces")
    faces = faces[keep[label]]
    used = np.unique(faces)
    remap = np.full(len(vertices), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return vertices[used], remap[faces].astype(np.int32)


# --- orientation and units ------------------------------------------------------------------------


def _orient_y_up(vertices: np.ndarray, faces: np.ndarray, notes: list[str]) -> np.ndarray:
    """Rotate a clearly z-up garment to y up, (x, y, z) -> (x, z, -y) (-90 degrees about x), so that
    the front (-y in z-up tools such as Blender and 3ds Max) faces +z.

    The evidence is the garment's largest opening (hem, waist): it is horizontal when worn, so its
    plane's normal is the up axis. Without a usable opening, the extents decide: a garment is thin front
    to back, so y up means z is not the largest extent while y is the smallest.
    """
    up = _largest_opening_normal(vertices, faces)
    if up is not None:
        z_up = abs(up[2]) > LOOP_AXIS_COS
    else:
        ext = np.ptp(vertices, axis=0)
        z_up = ext[1] < ext[2] and ext[1] <= ext[0] and ext[2] >= 1.5 * ext[1]
    if z_up:
        notes.append("the file is z up: rotated to y up")
        return np.column_stack([vertices[:, 0], vertices[:, 2], -vertices[:, 1]])
    return vertices


def _largest_opening_normal(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray | None:
    """Unit normal of the plane of the longest boundary loop, if that loop is roughly planar."""
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1).astype(np.int64)
    n = len(vertices)
    key, count = np.unique(e[:, 0] * n + e[:, 1], return_counts=True)
    b = key[count == 1]
    if len(b) < 3:
        return None
    a, c = b // n, b % n
    graph = scipy.sparse.coo_matrix((np.ones(len(b)), (a, c)), shape=(n, n))
    _, label = scipy.sparse.csgraph.connected_components(graph, directed=False)
    length = np.bincount(label[a], weights=np.linalg.norm(vertices[a] - vertices[c], axis=1), minlength=n)
    loop = np.unique(np.concatenate([a, c])[label[np.concatenate([a, c])] == np.argmax(length)])
    if len(loop) < 6:
        return None
    pts = vertices[loop] - vertices[loop].mean(axis=0)
    _, spread, vt = np.linalg.svd(pts, full_matrices=False)
    if spread[2] > LOOP_FLATNESS * spread[1]:
        return None  # not a plane (a wavy or folded edge): no evidence
    return vt[2]


def _to_metres(vertices: np.ndarray, units: str, notes: list[str]) -> tuple[np.ndarray, str, bool]:
    """Scale to metres by declared units, or guess them (``auto``) from the garment's size."""
    ext = np.ptp(vertices, axis=0)
    height, width = ext[1], ext[0]
    if units != "auto":
        scale = UNIT_SCALE[units]
        size = max(ext) * scale
        if not SANE_SIZE_M[0] <= size <= SANE_SIZE_M[1]:
            raise GarmentError(
                f"read as {units}, the garment would be {size:.3g} m across: check the units (or use auto)"
            )
        return vertices * scale, units, False
    if max(ext) <= 0:
        raise GarmentError("the mesh has no extent (all vertices at one point)")
    for unit in AUTO_PREFERENCE:
        s = UNIT_SCALE[unit]
        if (WEARABLE_HEIGHT_M[0] <= height * s <= WEARABLE_HEIGHT_M[1]
                and WEARABLE_WIDTH_M[0] <= width * s <= WEARABLE_WIDTH_M[1]):
            notes.append(
                f"units guessed as {unit}: then the garment is {height * s * 100:.0f} cm tall and "
                f"{width * s * 100:.0f} cm wide"
            )
            return vertices * s, unit, True
    raise GarmentError(
        f"cannot guess the units: the garment is {height:.4g} x {width:.4g} (height x width) file units, "
        "which is not a wearable size in m, cm, mm, dm or in; declare the units"
    )
