"""Load any garment mesh file into a clean triangle mesh in metres, y up (SPEC section 3).

``load_garment(data, filename, units, max_faces) -> CleanMesh``: read with trimesh, weld, split quads,
drop degenerate/duplicate faces and specks, orient y up, convert to metres. Everything refused raises
``GarmentError`` with a reason a user can act on, in the project's own words: a reader library's
exception text is logged for developers, never shown to a user.
"""

from __future__ import annotations

import io
import logging
import re
import struct
import warnings
from dataclasses import dataclass, field
from pathlib import PurePosixPath, PureWindowsPath

import numpy as np
import scipy.sparse
import scipy.sparse.csgraph
import trimesh

from tryon.garment.topology import boundary_loops, vertex_pieces

log = logging.getLogger(__name__)

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
# Declared units are trusted within wider bounds than the guess's (a child's garment, a long train, a
# panel lying flat), but units that make the garment's largest extent under 15 cm (6 cm: a T-shirt in cm
# declared as mm) or over 3 m make it no garment a person wears: they are wrong.
DECLARED_SIZE_M = (0.15, 3.0)

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
# A text format (OBJ, OFF, ASCII STL, glTF) with more than this fraction of control bytes (other than
# tab, line feed, carriage return, form feed, and the DOS end-of-file mark) is binary data: random bytes
# have 11%, a text file none or a stray one.
MAX_CONTROL_BYTE_FRACTION = 0.001
# Fewer triangles than this cannot drape as cloth (a box has 12; the smallest real garment we have seen,
# the MakeHuman outfits' pieces, about 2,000): the simulation needs a surface that can fold.
MIN_FACES = 24
# Largest coordinate a garment file may hold, in its own units: 1,000 km even in millimetres (the smallest
# unit read). A larger one (1e30, 3.4e38: a broken export) is no garment's in any units; a whole garment
# drawn too large is refused by its size, with the units (``_to_metres``).
MAX_COORDINATE = 1e9
# A vertex of the garment's surface farther out than this many times the garment's size (the span of its
# vertices from the 1st to the 99th percentile) from the box of that span is a stray vertex (a spike).
STRAY_FACTOR = 10.0
# An opening for the body (a neck, hem, cuff, waist or leg opening) is an open edge loop at least this long
# (m): a hand goes through a cuff of about 17 cm (the MakeHuman blouse's; every garment we have has two
# openings of 37 cm or more). A smaller loop is a hole in the cloth (the DiffCloth dress's two: 3 and 6 cm).
MIN_OPENING_M = 0.15
# Openings each piece of a garment needs: the body goes in through one and out through another (a skirt's
# waist and hem; a top's neck, hem and sleeves). A sheet's only open edge is its rim: it cannot be worn.
MIN_OPENINGS = 2


class GarmentError(ValueError):
    """A garment file was refused; ``str(error)`` is a reason a user can act on.

    ``status`` is the HTTP status the service answers with: 422 (a file it cannot use), 415 (a file
    type it does not read), 413 (too large), 400 (a bad file name), 409 (it conflicts with an entry already
    in); ``field`` the request field it is about (the file, unless said)."""

    def __init__(self, message: str, status: int = 422, field: str = "file"):
        super().__init__(message)
        self.status = status
        self.field = field


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
    data = _readable(data, ext, filename)
    vertices, faces = _read(data, ext, filename, max_faces)
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
    _refuse_unwearable(faces, len(vertices))
    _refuse_without_openings(vertices, faces, in_metres=False)
    vertices = _orient_y_up(vertices, faces, notes)
    vertices, units, guessed = _to_metres(vertices, units, notes)
    _refuse_without_openings(vertices, faces, in_metres=True)
    return CleanMesh(vertices=vertices, faces=faces, units=units, units_guessed=guessed, notes=notes)


# --- reading --------------------------------------------------------------------------------------


def _unreadable(filename: str, ext: str, reason: str) -> GarmentError:
    """The refusal of a file that is not the format its name says, with our reason."""
    return GarmentError(f"{filename} is not a readable {_format_name(ext)} file: {reason}")


def _format_name(ext: str) -> str:
    return "glTF" if ext == "gltf" else ext.upper()


def check_readable(data: bytes, filename: str) -> None:
    """GarmentError if ``data`` is visibly not the format its ``filename`` says (``_readable``'s checks, no
    parsing): what a re-upload of a file already in the catalogue is checked for under its new name."""
    _readable(data, file_extension(filename), filename)


def _readable(data: bytes, ext: str, filename: str) -> bytes:
    """Refuse, in our words, a file that is visibly not its format (the reader libraries' own messages
    are internal: "Not a ply file!", "No module named 'charset_normalizer'"); return the bytes to read,
    text formats as UTF-8 (trimesh refuses other encodings)."""
    if ext == "stl":
        if _is_binary_stl(data):
            return data
        if _looks_binary(data):
            raise _unreadable(filename, ext, "it is binary data, but its length does not match the triangle "
                                             "count in its header (a binary STL that is truncated or damaged)")
    if ext in ("obj", "off", "gltf", "stl"):
        data = _as_utf8_text(data, ext, filename)
    if ext == "obj":
        data = _check_obj_text(data)
    elif ext == "off":
        _check_off_header(data, filename)
    elif ext == "stl" and not data.lstrip()[:5].lower() == b"solid":
        raise _unreadable(filename, ext, "it is neither a binary STL nor STL text (which starts with 'solid')")
    elif ext == "ply":
        _check_ply_header(data, filename)
    elif ext == "glb":
        _check_glb_header(data, filename)
    elif ext == "gltf" and not data.lstrip().startswith(b"{"):
        raise _unreadable(filename, ext, "it is not glTF JSON text (which starts with '{')")
    return data


def _as_utf8_text(data: bytes, ext: str, filename: str) -> bytes:
    """The text of a text format as UTF-8 without a byte order mark; a file in another 8-bit encoding
    (a Latin-1 comment or material name) is read as Latin-1. Refuses binary data and UTF-16."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise _unreadable(filename, ext, "it is UTF-16 text: save it as UTF-8 or ASCII text")
    if _looks_binary(data):
        raise _unreadable(filename, ext, f"it is binary data, not {_format_name(ext)} text")
    data = data.removeprefix(b"\xef\xbb\xbf")
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1").encode("utf-8")
    return data


# Bytes a text file may hold: printable ASCII, tab, line feed, carriage return, form feed, the DOS
# end-of-file mark (0x1a), and every byte of 0x80 and above (UTF-8 or another 8-bit encoding).
_TEXT_BYTES = bytes([9, 10, 12, 13, 26, *range(32, 127), *range(128, 256)])


def _looks_binary(data: bytes) -> bool:
    """True for data with a NUL byte or more control bytes than a text file has."""
    return b"\x00" in data or len(data.translate(None, _TEXT_BYTES)) > MAX_CONTROL_BYTE_FRACTION * len(data)


def _check_off_header(data: bytes, filename: str) -> None:
    """An OFF file starts (after comments) with the keyword OFF, or COFF for one with colours."""
    for line in data[:1 << 16].splitlines():
        words = line.split(b"#", 1)[0].split()
        if not words:
            continue
        keyword = words[0].decode("latin-1")
        if keyword.upper() in ("OFF", "COFF"):
            return
        if keyword.upper().endswith("OFF"):
            raise _unreadable(filename, "off", f"its header {keyword!r} is an OFF variant that is not read: "
                                               "save it as plain OFF")
        break
    raise _unreadable(filename, "off", "its first line is not an OFF header (the word OFF)")


def _is_binary_stl(data: bytes) -> bool:
    """A binary STL is an 80-byte header, a triangle count n and 50 bytes per triangle."""
    return len(data) >= 84 and len(data) == 84 + 50 * struct.unpack_from("<I", data, 80)[0]


def _check_ply_header(data: bytes, filename: str) -> None:
    """A PLY file starts with the line ``ply`` and its header ends with ``end_header``."""
    if not data.startswith((b"ply\n", b"ply\r\n", b"ply \n", b"ply\r")):
        raise _unreadable(filename, "ply", "its header is not a PLY header (a PLY file starts with the "
                                           "line 'ply')")
    if b"end_header" not in data[:1 << 16]:
        raise _unreadable(filename, "ply", "its header has no 'end_header' line: the file is truncated")


def _check_glb_header(data: bytes, filename: str) -> None:
    """A GLB file starts with ``glTF``, version 2 and its length in bytes."""
    if len(data) < 12 or data[:4] != b"glTF":
        raise _unreadable(filename, "glb", "its header is not a GLB header (a GLB file starts with "
                                           "'glTF')")
    version, length = struct.unpack_from("<II", data, 4)
    if version == 1:
        raise _unreadable(filename, "glb", "it is glTF 1.0; only glTF 2.0 is read: export it again")
    if version != 2:
        raise _unreadable(filename, "glb", f"its header names no glTF version (it says {version}): the file "
                                           "is damaged")
    if length > len(data):
        raise _unreadable(filename, "glb", f"its header says {length:,} bytes but the file has "
                                           f"{len(data):,}: it is truncated")


def _read(data: bytes, ext: str, filename: str, max_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """Parse with trimesh (no processing), weld UV/normal seams, return raw float64/int64 arrays."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            loaded = trimesh.load(io.BytesIO(data), file_type=ext, process=False)
            if isinstance(loaded, trimesh.Scene):
                geoms = ([g for g in loaded.dump(concatenate=False) if isinstance(g, trimesh.Trimesh)]
                         if loaded.geometry else [])
                loaded = (trimesh.util.concatenate(geoms) if len(geoms) > 1 else geoms[0]) if geoms else None
    except Exception as exc:  # trimesh raises many types for broken files
        if ext == "gltf" and b'"uri"' in data and b'"data:' not in data:
            raise GarmentError(
                "this .gltf refers to separate buffer files, which were not uploaded: export a single .glb "
                "(or a .gltf with embedded buffers)"
            ) from exc
        log.warning("trimesh could not read %s as %s: %s: %s", filename, ext, type(exc).__name__, exc)
        log.debug("trimesh's traceback for %s", filename, exc_info=exc)
        raise _unreadable(filename, ext, "it is damaged or truncated (its content does not follow the "
                                         f"{_format_name(ext)} format)") from None
    if loaded is None:
        raise GarmentError("the file has no triangle or quad faces (no mesh in the scene)")
    if isinstance(loaded, trimesh.PointCloud):
        raise GarmentError("the file is a point cloud (vertices without faces): a garment needs faces"
                           + _cut_before_faces(ext, data))
    if not isinstance(loaded, trimesh.Trimesh):
        log.info("%s holds a %s", filename, type(loaded).__name__)
        raise GarmentError("the file holds lines or curves, not a surface mesh with faces")
    faces = np.asarray(loaded.faces)
    if faces.size == 0:
        raise GarmentError("the file has no faces (a point cloud or empty mesh): a garment needs faces"
                           + _cut_before_faces(ext, data))
    if len(faces) > max_faces:
        raise GarmentError(f"the mesh has {len(faces):,} faces, more than the limit of {max_faces:,}", 413)
    vertices = np.asarray(loaded.vertices, dtype=np.float64)
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise GarmentError("the file has faces that refer to vertices that do not exist")
    _refuse_bad_coordinates(vertices, faces, data, ext)
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    # trimesh keeps vertices apart at UV and normal seams unless told: weld by position only.
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)


def _refuse_bad_coordinates(vertices: np.ndarray, faces: np.ndarray, data: bytes, ext: str) -> None:
    """Refuse a file with a coordinate that is not a number (NaN, infinity), beyond ``MAX_COORDINATE``, or
    a stray vertex of the surface far out of the garment (``STRAY_FACTOR``), naming the vertex, its value and
    the limit. ``vertices`` (n, 3) and ``faces`` (f, 3) as read (before welding). Checked before anything is
    measured: one vertex at 1e30 made every other triangle look degenerate beside its own, and the file was
    refused as having 3 triangles."""
    bad = ~np.isfinite(vertices) | (np.abs(np.nan_to_num(vertices, nan=0.0)) > MAX_COORDINATE)
    if bad.any():
        i, axis = (int(k) for k in np.argwhere(bad)[0])
        value = vertices[i, axis]
        where = _vertex_named(data, ext, i, lambda rows: np.flatnonzero(
            (~np.isfinite(rows) | (np.abs(np.nan_to_num(rows, nan=0.0)) > MAX_COORDINATE)).any(axis=1)))
        if not np.isfinite(value):
            raise GarmentError(f"{where} has a non-finite coordinate, {'xyz'[axis]} = {value}: every coordinate "
                               "must be a finite number (not NaN or infinity)")
        raise GarmentError(f"{where} has an absurd coordinate, {'xyz'[axis]} = {value:g}: a garment's coordinates "
                           f"are at most {MAX_COORDINATE:,.0f} either way (1,000 km even in millimetres): fix or "
                           "remove that vertex")
    used = np.unique(faces)
    if len(used) < 8:
        return  # too few to tell a garment from a stray vertex (refused as too few triangles later)
    lo, hi = np.percentile(vertices[used], [1.0, 99.0], axis=0)
    size = float(np.max(hi - lo))
    if size <= 0.0:
        return
    out = np.max(np.maximum(lo - vertices, vertices - hi), axis=1)  # (n,) how far outside the box
    stray = np.zeros(len(vertices), dtype=np.bool_)
    stray[used] = out[used] > STRAY_FACTOR * size
    if not stray.any():
        return
    # a stray vertex of the garment's own surface (a spike), not a separate piece placed far away (a speck,
    # dropped later with the other specks)
    _, piece = vertex_pieces(faces, len(vertices))
    inside = np.zeros(int(piece.max()) + 1, dtype=np.bool_)
    inside[piece[used[~stray[used]]]] = True
    spikes = np.flatnonzero(stray & inside[piece])
    if not len(spikes):
        return
    i = int(spikes[np.argmax(out[spikes])])
    axis = int(np.argmax(np.maximum(lo - vertices[i], vertices[i] - hi)))
    position = vertices[i]
    where = _vertex_named(data, ext, i, lambda rows: np.flatnonzero((rows == position).all(axis=1)))
    raise GarmentError(
        f"{where} is a stray vertex: its {'xyz'[axis]} = {vertices[i, axis]:g} is {out[i] / size:,.0f} times "
        f"the garment's size ({size:.4g} file units across its other vertices) away from them, more than the "
        f"limit of {STRAY_FACTOR:g} times: fix or remove that vertex")


def _vertex_named(data: bytes, ext: str, index: int, find) -> str:
    """A vertex for a message: in an OBJ, its number among the file's ``v`` lines and its line (found by
    ``find(rows)``: the matching rows of the file's (n, 3) vertex coordinates, in file order; the reader may
    have dropped or reordered vertices); in another format, ``index`` + 1 in the order it was read."""
    if ext == "obj":
        text = b"\n" + data
        starts = [m.start() for m in re.finditer(rb"\nv[ \t]", text)]
        rows = _obj_vertex_rows(data)
        hits = find(rows) if rows is not None and len(rows) == len(starts) else []
        if len(hits):
            k = int(hits[0])
            line = text.count(b"\n", 0, starts[k] + 1)
            return f"vertex {k + 1:,} (line {line:,})"
    return f"vertex {index + 1:,}"


def _obj_vertex_rows(data: bytes) -> np.ndarray | None:
    """(n, 3) float64: the first three numbers of every ``v`` line of an OBJ's text, in file order; None if
    one does not read as a number."""
    rows = re.findall(rb"(?m)^v[ \t]+(\S+)[ \t]+(\S+)[ \t]+(\S+)", data)
    try:
        return np.array(rows, dtype=np.float64).reshape(-1, 3)
    except ValueError:
        return None


def _unused_fraction(data: bytes, ext: str, vertices: np.ndarray, faces: np.ndarray) -> float:
    """Fraction of the file's distinct vertex positions that no face uses. trimesh's OBJ reader drops
    unused vertices, so for OBJ the ``v`` lines are counted from the text."""
    used = len(np.unique(vertices[np.unique(faces)], axis=0))
    if ext != "obj":
        return 1.0 - used / max(len(np.unique(vertices, axis=0)), 1)
    rows = _obj_vertex_rows(data)
    if rows is None:
        return 0.0  # unparsable numbers: trimesh read them somehow; do not guess
    total = len(np.unique(rows, axis=0)) if len(rows) else used
    return 1.0 - used / max(total, used, 1)


# --- OBJ text check -------------------------------------------------------------------------------
# trimesh reads "f 12 13 1267/" (a file cut in the middle of its last face) as a whole face, "f 0 1 2"
# as a face on the last vertex, and refuses "f 1 2 x" with numpy's words. One search with a regular
# expression finds the first v/vt/vn/f line that does not parse, numpy checks every face's vertex index
# (together about 1 s for a 50 MB file of 440,000 faces, at C speed); only a bad line is then taken
# apart in Python, for the message. The text is searched with a line break in front, so that every
# line starts after one (a search for a line break is much faster than one for the start of a line).

# One number of a v/vt/vn line: a decimal with an optional exponent, or nan/inf (refused later, in
# ``_read``, as non-finite). Atomic groups and possessive quantifiers keep the search linear, even on a
# line of a million digits. An optional group is greedy, not possessive (inside the atomic group it is as
# linear): Python 3.11.2's re (Debian 12's) matches "1e" and "3/" whole with a possessive optional group.
_NUMBER = rb"(?>[-+]?+(?:\d++(?:\.\d*+)?|\.\d++)(?:[eE][-+]?+\d++)?|[-+]?+(?i:nan|inf(?:inity)?))"
# One corner of a face: v, v/vt, v//vn or v/vt/vn, each a whole number (negative: counted back).
_CORNER = rb"(?>[-+]?+\d++(?:/[-+]?+\d*+/[-+]?+\d++|/[-+]?+\d++)?)"
# After a keyword: a blank (a longer word such as "vp" or "fo" is another keyword).
_KEYWORD_END = rb"(?![^ \t\r\n])"
# The end of a good line: blanks and the line break (trimesh reads no comment after data on a line).
_END = rb"[ \t\r]*+(?=\n|\Z)"
# The first v, vt, vn or f line that is not at least 3 numbers (v, vn), 1 number (vt), 3 corners (f).
_BAD_OBJ_LINE = re.compile(
    rb"\n(?:v" + _KEYWORD_END + rb"(?![ \t]++" + _NUMBER + rb"(?:[ \t]++" + _NUMBER + rb"){2,}+" + _END + rb")"
    rb"|vn" + _KEYWORD_END + rb"(?![ \t]++" + _NUMBER + rb"(?:[ \t]++" + _NUMBER + rb"){2,}+" + _END + rb")"
    rb"|vt" + _KEYWORD_END + rb"(?![ \t]++" + _NUMBER + rb"(?:[ \t]++" + _NUMBER + rb")*+" + _END + rb")"
    rb"|f" + _KEYWORD_END + rb"(?![ \t]++" + _CORNER + rb"(?:[ \t]++" + _CORNER + rb"){2,}+" + _END + rb"))"
)
# A run of consecutive face lines (after the check above: "f", a blank, corners).
_FACE_RUN = re.compile(rb"(?:\nf[ \t][^\n]*+)++")
# One face line, its corners in group 1 (for the messages).
_FACE_LINE = re.compile(rb"\nf[ \t]++([^\r\n]*+)")
# A comment after the data of a v, vt, vn or f line (the data is group 1).
_DATA_COMMENT = re.compile(rb"(\n(?:v[tn]?+|f)[ \t][^#\r\n]*+)#[^\r\n]*+")
# What each token of a v, vt, vn or f line is, and how many a line needs: for the messages.
_OBJ_LINE_KINDS = {
    b"v": ("vertex coordinate", 3, "a vertex needs 3 coordinates (x y z)"),
    b"vn": ("normal coordinate", 3, "a normal needs 3 coordinates"),
    b"vt": ("texture coordinate", 1, "a texture coordinate needs at least 1 number"),
    b"f": ("face index", 3, "a face needs at least 3 vertices"),
}


def _check_obj_text(data: bytes) -> bytes:
    """Refuse an OBJ whose v/vt/vn/f lines do not parse or whose faces name vertices that do not exist,
    naming the line and the token; a file cut in the middle of a line is called truncated. Returns the
    text for trimesh, which reads neither a comment after data on a line (removed here, only in a file
    that has one), nor a line continued with a backslash (joined), nor a tab after a keyword (a space)."""
    text = b"\n" + data
    if b"\\\n" in text or b"\\\r\n" in text:
        # joined as trimesh would join them (later line numbers are then off by the number of joins:
        # rare, and the token is still named)
        text = text.replace(b"\\\r\n", b"").replace(b"\\\n", b"")
    # trimesh reads "v 1 2 3", not "v<tab>1 2 3" (and the v lines are counted below as "\nv ")
    for keyword in (b"v", b"vt", b"vn", b"f"):
        text = text.replace(b"\n" + keyword + b"\t", b"\n" + keyword + b" ")
    bad = _BAD_OBJ_LINE.search(text)
    if bad is not None and b"#" in _line_at(text, bad.start())[1]:
        text = _DATA_COMMENT.sub(rb"\1", text)
        bad = _BAD_OBJ_LINE.search(text)
    if bad is not None:
        raise GarmentError(_bad_line_message(text, bad.start()))
    _check_face_indices(text)
    return text[1:]


def _line_at(text: bytes, newline: int) -> tuple[int, bytes, bool]:
    """(1-based line number, the line without its break, whether the file ends in the middle of it: it is
    the last line, without a line break) of the line after the line break at ``newline`` of ``text``
    (the file with a line break in front)."""
    end = text.find(b"\n", newline + 1)
    line = text[newline + 1:] if end < 0 else text[newline + 1:end]
    return text.count(b"\n", 0, newline + 1), line.rstrip(b"\r"), end < 0


def _shown(token: bytes) -> str:
    """A token of a file, quoted, cut short if long (a line of a million digits is not sent back whole)."""
    text = token.decode("utf-8", "replace")  # the checked text is UTF-8
    return repr(text) if len(text) <= 40 else repr(text[:30] + "...") + f" ({len(text):,} characters)"


def _cut_before_faces(ext: str, data: bytes) -> str:
    """What to add to "no faces" for an OBJ that ends in the middle of a line (no final line break): its
    faces come after its vertices, so it was most likely cut off before them."""
    if ext != "obj" or data.rstrip(b" \t").endswith((b"\n", b"\r")):
        return ""
    return ("; the file ends in the middle of a line, so it looks truncated: its faces, which follow the "
            "vertices, are missing")


def _truncated(cut: bool) -> str:
    return ": the file ends in the middle of this line, it is truncated" if cut else ""


def _bad_line_message(text: bytes, newline: int) -> str:
    """Why the v/vt/vn/f line after ``newline`` does not parse: its first bad token, or too few."""
    number, line, cut = _line_at(text, newline)
    keyword, *tokens = re.split(rb"[ \t]+", line.strip(b" \t\r"))
    what, least, needs = _OBJ_LINE_KINDS[keyword]
    good = re.compile(_CORNER if keyword == b"f" else _NUMBER)
    for token in tokens:
        if good.fullmatch(token) is None:
            form = ("a face lists vertex numbers such as 12, 12/5, 12//7 or 12/5/7" if keyword == b"f"
                    else "a coordinate is a decimal number such as -0.25 or 1.5e-3")
            return f"line {number}: {what} {_shown(token)} does not parse ({form}){_truncated(cut)}"
    if len(tokens) < least:
        return f"line {number}: {needs}, this one has {len(tokens)}{_truncated(cut)}"
    return f"line {number}: the line does not parse (it has characters other than numbers and blanks)"


def _check_face_indices(text: bytes) -> None:
    """Every face's vertex index names an existing vertex: 1..(vertices in the file), or a negative one
    counting back from the last vertex before its line. vt/vn indices are not checked (not read)."""
    index, before = _face_corners(text)
    n_vertices = text.count(b"\nv ")
    bad = (index == 0) | (index > n_vertices) | (index < -before)  # (-index overflows at -2**63)
    if bad.any():
        raise GarmentError(_bad_index_message(text, int(np.argmax(bad)), n_vertices))


def _face_corners(text: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Every face corner of the checked ``text`` (with a line break in front), in file order: (corners,)
    int64 its vertex index (the number before its first '/'), and (corners,) int64 how many v lines come
    before its line. One Python step per run of consecutive face lines, not per line."""
    runs, before, seen, at = [], [], 0, 0
    for m in _FACE_RUN.finditer(text, max(text.find(b"\nf"), 0)):
        seen += text.count(b"\nv ", at, m.start())
        at = m.end()
        runs.append(m.group().replace(b"\nf", b"\n ").replace(b"//", b"/0/"))  # each '/' between numbers
        before.append(seen)
    if not runs:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    faces = b"".join(runs)
    c = np.frombuffer(faces, dtype=np.uint8)
    in_number = ((c >= ord("0")) & (c <= ord("9"))) | (c == ord("-")) | (c == ord("+"))
    starts = in_number.copy()
    starts[1:] &= ~in_number[:-1]
    corner = starts.copy()
    corner[1:] &= c[:-1] != ord("/")  # a number not after a '/' starts a corner
    numbers = np.fromstring(faces.replace(b"/", b" "), dtype=np.int64, sep=" ")
    offsets = np.cumsum([0] + [len(r) for r in runs[:-1]])
    per_run = np.add.reduceat(corner, offsets, dtype=np.int64)
    return numbers[corner[starts]], np.repeat(np.array(before, dtype=np.int64), per_run)


def _face_lines(text: bytes) -> list[tuple[int, list[bytes]]]:
    """(line break before it, its corners) of every face line: the slow way, for a message."""
    return [(m.start(), m.group(1).split()) for m in _FACE_LINE.finditer(text)]


def _bad_index_message(text: bytes, corner: int, n_vertices: int) -> str:
    """Why face corner number ``corner`` (counted over the whole file) names no vertex, with its line."""
    lines = _face_lines(text)
    ends = np.cumsum([len(corners) for _, corners in lines])
    row = int(np.searchsorted(ends, corner, side="right"))
    newline, corners = lines[row]
    number, _, cut = _line_at(text, newline)
    token = corners[corner - (int(ends[row - 1]) if row else 0)]
    value = int(token.split(b"/")[0])
    if value == 0:
        reason = "is 0, but OBJ counts vertices from 1"
    elif value > 0:
        reason = f"names vertex {value:,}, but the file has only {n_vertices:,} vertices"
    else:
        before = text.count(b"\nv ", 0, newline)
        reason = f"counts back {-value:,} vertices, but only {before:,} come before this line"
    return f"line {number}: face index {_shown(token)} {reason}{_truncated(cut)}"


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


def _refuse_unwearable(faces: np.ndarray, n_vertices: int) -> None:
    """Refuse a mesh that cannot be put on and draped: too few triangles to fold (``MIN_FACES``), or a closed
    surface (no open edge at all: a solid box, a ball, a body scan), which has no opening for the head,
    arms, waist or legs."""
    if len(faces) < MIN_FACES:
        raise GarmentError(f"the mesh has {len(faces)} triangle{'s' if len(faces) != 1 else ''}, too few to drape as "
                           f"cloth (at least {MIN_FACES}): upload the garment's full mesh")
    if not boundary_loops(faces, n_vertices):
        raise GarmentError("the mesh is a closed surface (no open edge anywhere): a garment has openings for the "
                           "body (neck, arms, waist, legs); a solid object or a body scan cannot be worn")


def _refuse_without_openings(vertices: np.ndarray, faces: np.ndarray, in_metres: bool) -> None:
    """Refuse, whatever the category, a garment of which a piece has fewer than ``MIN_OPENINGS`` openings for
    the body: open edge loops, and once ``in_metres`` only those at least ``MIN_OPENING_M`` around (a smaller
    loop is a hole in the cloth). A flat or cupped sheet has one open edge, its rim: nothing goes through it,
    so it cannot be put on. ``vertices`` (n, 3), ``faces`` (f, 3) of the cleaned mesh (after
    ``_largest_components``); checked before the units are known (loops counted: a sheet is refused as such,
    not for the size its flatness gives) and again in metres (holes told from openings)."""
    count, piece = vertex_pieces(faces, len(vertices))
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1).astype(np.int64)
    n = len(vertices)
    key, times = np.unique(e[:, 0] * n + e[:, 1], return_counts=True)
    b = key[times == 1]
    a, c = b // n, b % n
    graph = scipy.sparse.coo_matrix((np.ones(len(b)), (a, c)), shape=(n, n))
    loop = scipy.sparse.csgraph.connected_components(graph, directed=False)[1][a]  # each open edge's loop
    loops, first = np.unique(loop, return_index=True)
    length = np.bincount(np.searchsorted(loops, loop), weights=np.linalg.norm(vertices[a] - vertices[c], axis=1),
                         minlength=len(loops))
    loop_piece = piece[a[first]]
    area = np.bincount(piece[faces[:, 0]], weights=_face_areas(vertices, faces), minlength=count)
    least = MIN_OPENING_M if in_metres else 0.0
    for p in np.argsort(-area):  # the largest piece first
        own = np.sort(length[loop_piece == p])[::-1]
        openings = int(np.count_nonzero(own >= least))
        if openings >= MIN_OPENINGS:
            continue
        which = ("the mesh" if count == 1 else
                 f"a piece of the mesh ({area[p] / area.sum():.0%} of its cloth, {count} pieces in all)")
        if len(own) == 0:
            has, why = "no opening", "it is a closed surface (no open edge)"
        elif len(own) == 1:
            rim = f", {_length(own[0])} around" if in_metres else ""
            has, why = "no opening", f"its only open edge is its rim{rim} (a sheet, or a sack)"
        else:
            holes = len(own) - openings
            has = "only one opening" if openings == 1 else "no opening"
            why = (f"of its {len(own)} open edges, {holes} {'is a hole' if holes == 1 else 'are holes'} in the "
                   f"cloth under {_length(MIN_OPENING_M)} around")
        raise GarmentError(
            f"{which} has {has} for the body: {why}. A garment has at least {MIN_OPENINGS} openings the body goes "
            f"through, each at least {_length(MIN_OPENING_M)} around (a skirt's waist and hem; a top's neck, hem "
            "and sleeves), whatever its category: a flat sheet or a sack cannot be worn; upload the sewn garment")


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


def _length(metres: float) -> str:
    """A length for a message: in m from 1 m, cm from 1 cm, else mm."""
    if metres >= 1.0:
        return f"{metres:.3g} m"
    return f"{metres * 100:.3g} cm" if metres >= 0.01 else f"{metres * 1000:.3g} mm"


def _to_metres(vertices: np.ndarray, units: str, notes: list[str]) -> tuple[np.ndarray, str, bool]:
    """Scale to metres by declared units, or guess them (``auto``) from the garment's size."""
    ext = np.ptp(vertices, axis=0)
    height, width = ext[1], ext[0]
    if units != "auto":
        scale = UNIT_SCALE[units]
        size = max(ext) * scale
        if not DECLARED_SIZE_M[0] <= size <= DECLARED_SIZE_M[1]:
            raise GarmentError(
                f"read as {units}, the garment would be {_length(height * scale)} tall and {_length(width * scale)} "
                f"wide: no garment a person wears is {'that small' if size < DECLARED_SIZE_M[0] else 'that large'}; "
                "check the units (or use auto)"
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
