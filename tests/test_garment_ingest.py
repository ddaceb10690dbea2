"""Loading garment files: formats, welding, cleaning, orientation, units, and every refusal."""

import numpy as np
import pytest
import trimesh

from tryon.garment.generate import garment_mesh, obj_text
from tryon.garment.ingest import GarmentError, load_garment


@pytest.fixture(scope="module")
def tshirt() -> trimesh.Trimesh:
    return garment_mesh("tshirt", "M")


def obj_bytes(v: np.ndarray, f: np.ndarray) -> bytes:
    return obj_text(trimesh.Trimesh(v, f, process=False), "test").encode()


def quad_obj(around: int, rows: int, spacing: float) -> bytes:
    """A quad tube (a plain skirt: a flat sheet has no opening for the body and is refused), ``around`` quads
    round and ``rows`` high, ``spacing`` m tall each, with ``f a b c d`` quad lines."""
    r = 0.2
    lines = [f"v {r * np.cos(2 * np.pi * i / around):.6f} {j * spacing} {r * np.sin(2 * np.pi * i / around):.6f}"
             for j in range(rows + 1) for i in range(around)]
    for j in range(rows):
        for i in range(around):
            a, b = j * around + i + 1, j * around + (i + 1) % around + 1
            lines.append(f"f {a} {b} {b + around} {a + around}")
    return ("\n".join(lines) + "\n").encode()


@pytest.mark.parametrize("unit,scale", [("m", 1.0), ("cm", 100.0), ("mm", 1000.0), ("dm", 10.0), ("in", 1 / 0.0254)])
def test_units_declared(tshirt, unit, scale):
    m = load_garment(obj_bytes(tshirt.vertices * scale, tshirt.faces), "t.obj", unit)
    assert m.units == unit and not m.units_guessed
    assert np.allclose(m.vertices, tshirt.vertices, atol=1e-3)


@pytest.mark.parametrize("unit,scale", [("m", 1.0), ("cm", 100.0), ("mm", 1000.0), ("dm", 10.0)])
def test_units_guessed_metric(tshirt, unit, scale):
    m = load_garment(obj_bytes(tshirt.vertices * scale, tshirt.faces), "t.obj", "auto")
    assert m.units == unit and m.units_guessed
    assert np.ptp(m.vertices[:, 1]) == pytest.approx(np.ptp(tshirt.vertices[:, 1]), rel=1e-3)
    assert any(f"guessed as {unit}" in n for n in m.notes)


def test_units_guessed_inches_when_centimetres_would_be_a_doll_dress():
    # a 0.92 m dress written in inches: as cm it would be 36 cm tall and 19 cm wide, too narrow to wear
    dress = garment_mesh("dress", "S")
    v = (dress.vertices - dress.vertices.min(axis=0)) / 0.0254 + [11.8, 26.7, -9.8]  # off the origin
    v[:, 0] *= 0.9
    m = load_garment(obj_bytes(v, dress.faces), "d.obj", "auto")
    assert m.units == "in" and m.units_guessed


def test_units_unguessable_and_absurd_declared_units_are_refused(tshirt):
    with pytest.raises(GarmentError, match="cannot guess the units"):
        load_garment(obj_bytes(tshirt.vertices * 1e5, tshirt.faces), "t.obj", "auto")
    with pytest.raises(GarmentError, match="check the units"):
        load_garment(obj_bytes(tshirt.vertices, tshirt.faces), "t.obj", "mm")


def test_z_up_file_is_rotated(tshirt):
    trousers = garment_mesh("trousers", "M")
    v = trousers.vertices
    z_up = np.column_stack([v[:, 0], -v[:, 2], v[:, 1]])  # y up -> z up, front towards -y
    m = load_garment(obj_bytes(z_up, trousers.faces), "t.obj", "m")
    assert any("z up" in n for n in m.notes)
    assert np.allclose(m.vertices, v, atol=1e-4)


def test_quads_split_into_triangles_and_follow_the_paper_springs():
    from tryon.garment.springs import spring_model

    m = load_garment(quad_obj(12, 5, 0.1), "q.obj", "m")
    assert len(m.faces) == 2 * 12 * 5 and len(m.vertices) == 12 * 6
    _, _, kind = spring_model(m.vertices, m.faces)
    assert np.bincount(kind, minlength=3)[1] == 2 * 12 * 5  # shear: both diagonals of every quad


def test_uv_seams_are_welded():
    # a tube whose texture coordinates are cut along one column: trimesh would split the seam
    n, rows = 12, 4
    lines = []
    for r in range(rows + 1):
        for k in range(n):
            t = 2 * np.pi * k / n
            lines.append(f"v {0.15 * np.cos(t):.5f} {0.1 * r:.5f} {0.15 * np.sin(t):.5f}")
    for r in range(rows + 1):
        for k in range(n + 1):
            lines.append(f"vt {k / n:.5f} {r / rows:.5f}")
    for r in range(rows):
        for k in range(n):
            a, b = r * n + k + 1, r * n + (k + 1) % n + 1
            ta, tb = r * (n + 1) + k + 1, r * (n + 1) + k + 2
            lines.append(f"f {a}/{ta} {b}/{tb} {b + n}/{tb + n + 1} {a + n}/{ta + n + 1}")
    m = load_garment(("\n".join(lines) + "\n").encode(), "tube.obj", "m")
    assert len(m.vertices) == n * (rows + 1)


def test_degenerate_and_duplicate_faces_dropped(tshirt):
    f = np.concatenate([tshirt.faces, tshirt.faces[:5], [[0, 0, 1], [3, 4, 3]]])
    m = load_garment(obj_bytes(tshirt.vertices, f), "t.obj", "m")
    assert len(m.faces) == len(tshirt.faces)
    assert any("duplicate" in n for n in m.notes)


def test_specks_dropped_and_two_big_pieces_kept(tshirt):
    trousers = garment_mesh("trousers", "M")
    speck_v = np.array([[0.0, 2.0, 0.0], [0.01, 2.0, 0.0], [0.0, 2.01, 0.0]])
    v = np.concatenate([tshirt.vertices, trousers.vertices, speck_v])
    nt, nb = len(tshirt.vertices), len(trousers.vertices)
    f = np.concatenate([tshirt.faces, trousers.faces + nt, [[nt + nb, nt + nb + 1, nt + nb + 2]]])
    m = load_garment(obj_bytes(v, f), "outfit.obj", "m")
    assert len(m.faces) == len(tshirt.faces) + len(trousers.faces)
    assert any("2 separate pieces" in n for n in m.notes)
    assert any("small loose pieces" in n for n in m.notes)


def flat_pattern_obj(stitches: int = 0) -> bytes:
    """Two flat, unsewn panels (front and back), with ``stitches`` Codim-IPC ``stitch a b c r`` lines."""
    panels = []
    for k, z in enumerate((0.3, -0.3)):  # two flat panels, front and back, not sewn
        xs, ys = np.meshgrid(np.linspace(-0.25, 0.25, 11), np.linspace(0.8, 1.4, 13))
        panels.append(np.column_stack([xs.ravel(), ys.ravel(), np.full(xs.size, z)]))
    v = np.concatenate(panels)
    f = []
    for p in range(2):
        base = p * 143
        for j in range(12):
            for i in range(10):
                a = base + j * 11 + i
                f += [[a, a + 1, a + 12], [a, a + 12, a + 11]]
    # each stitch sews a front side vertex to a point between two back side vertices (0-based ids)
    lines = "".join(f"stitch {j * 11} {143 + j * 11} {143 + (j + 1) * 11} 0.5\n" for j in range(stitches))
    return obj_bytes(v, np.array(f)) + lines.encode()


def test_flat_sewing_pattern_is_refused():
    with pytest.raises(GarmentError, match="flat sewing pattern") as err:
        load_garment(flat_pattern_obj(), "pattern.obj", "m")
    assert "stitch" not in str(err.value)


def test_flat_pattern_with_stitch_lines_is_refused_naming_them():
    with pytest.raises(GarmentError, match="its 12 'stitch' lines are not read: flat patterns with stitch "
                                           "lines are not supported") as err:
        load_garment(flat_pattern_obj(stitches=12), "pattern.obj", "m")
    assert err.value.status == 422


@pytest.mark.parametrize("fmt", ["ply", "stl", "off", "glb"])
def test_other_formats(tshirt, fmt):
    data = tshirt.export(file_type=fmt)
    data = data.encode() if isinstance(data, str) else data
    m = load_garment(data, f"t.{fmt}", "m")
    assert len(m.vertices) == len(tshirt.vertices)  # STL stores triangle soup: welded back
    assert len(m.faces) == len(tshirt.faces)


def test_gltf_scene_with_two_meshes_is_concatenated(tshirt):
    trousers = garment_mesh("trousers", "M")
    scene = trimesh.Scene([tshirt, trousers])
    m = load_garment(scene.export(file_type="glb"), "outfit.glb", "m")
    assert len(m.faces) == len(tshirt.faces) + len(trousers.faces)


BAD = [
    ("empty", b"", "t.obj", "empty"),
    ("garbage", b"\x00\x01garbage\xff" * 10, "t.obj", "t.obj is not a readable OBJ file: it is binary data"),
    ("garbage glb", b"glTF\x02\x00\x00\x00garbage", "t.glb", "t.glb is not a readable GLB file: .* truncated"),
    ("point cloud", b"v 0 0 0\nv 1 0 0\nv 0 1 0\n", "t.obj", "point cloud"),
    ("non-finite", b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "t.obj", "non-finite"),
    ("infinite", b"v inf 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "t.obj", "non-finite"),
    ("truncated ply", b"ply\nformat ascii 1.0\nelement vertex 3\n", "t.ply", "not a readable PLY file: .*no 'end_header'"),
    ("unknown ext", b"v 0 0 0\n", "t.xyz", "unknown file type"),
    ("no ext", b"v 0 0 0\n", "garment", "unknown file type"),
    ("3ds", b"MM\x00\x00", "t.3ds", "3DS files are not supported"),
    ("path", b"v 0 0 0\n", "../t.obj", "without a directory"),
    ("subdir", b"v 0 0 0\n", "a/t.obj", "without a directory"),
    ("windows path", b"v 0 0 0\n", "a\\t.obj", "without a directory"),
]


@pytest.mark.parametrize("label,data,name,match", BAD, ids=[b[0] for b in BAD])
def test_bad_files_are_refused_with_a_reason(label, data, name, match):
    with pytest.raises(GarmentError, match=match):
        load_garment(data, name, "auto")


def test_truncated_obj_is_refused(tshirt):
    # cut mid-line, or cut so that many faces are lost (their vertices are then unused). A cut that
    # leaves a complete-looking last line and loses only a few faces cannot be told from a whole file.
    data = obj_bytes(tshirt.vertices, tshirt.faces)
    for cut in (len(data) // 2, int(len(data) * 0.7) + 3, int(len(data) * 0.45)):
        with pytest.raises(GarmentError, match="truncated"):
            load_garment(data[:cut], "t.obj", "m")


def test_too_many_faces_refused(tshirt):
    with pytest.raises(GarmentError, match="more than the limit") as err:
        load_garment(obj_bytes(tshirt.vertices, tshirt.faces), "t.obj", "m", max_faces=1000)
    assert err.value.status == 413


def test_short_wide_skirt_is_not_taken_for_z_up():
    # a 20 cm mini skirt is shallower than it is deep; its hem is horizontal, so it is y up
    skirt = garment_mesh("skirt", "M")
    v = skirt.vertices * [1.0, 0.4, 1.0]
    assert np.ptp(v[:, 1]) < np.ptp(v[:, 2]) / 1.5
    m = load_garment(obj_bytes(v, skirt.faces), "mini.obj", "m")
    assert not any("z up" in n for n in m.notes)
    z_up = np.column_stack([v[:, 0], -v[:, 2], v[:, 1]])
    m = load_garment(obj_bytes(z_up, skirt.faces), "mini.obj", "m")
    assert any("z up" in n for n in m.notes)
    assert np.allclose(m.vertices, v, atol=1e-4)


def test_gltf_with_embedded_buffers_and_with_missing_ones():
    import base64
    import json

    skirt = garment_mesh("skirt", "S")
    files = skirt.export(file_type="gltf")
    with pytest.raises(GarmentError, match="separate buffer files"):
        load_garment(files["model.gltf"], "skirt.gltf", "m")
    gltf = json.loads(files["model.gltf"])
    for buffer in gltf["buffers"]:
        buffer["uri"] = "data:application/octet-stream;base64," + base64.b64encode(files[buffer["uri"]]).decode()
    m = load_garment(json.dumps(gltf).encode(), "skirt.gltf", "m")
    assert len(m.faces) == len(skirt.faces)
