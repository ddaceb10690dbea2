"""Mesh encodings for responses: JSON (SPEC section 6), GLB, OBJ; compact JSON of numpy-bearing objects."""

from __future__ import annotations

import json

import numpy as np
import trimesh

try:  # orjson writes the tens of thousands of coordinates of a mesh ~10-20x faster than the standard library
    import orjson
except ImportError:  # pragma: no cover - a declared dependency; the standard library does the same, slower
    orjson = None

MEDIA_TYPES = {"json": "application/json", "glb": "model/gltf-binary", "obj": "text/plain"}


def mesh_json(vertices: np.ndarray, faces: np.ndarray, decimals: int = 5) -> dict:
    """``{"vertices": [[x, y, z], ...], "faces": [[i, j, k], ...]}``; metres rounded to ``decimals``."""
    return {"vertices": np.round(vertices, decimals).tolist(), "faces": np.asarray(faces).tolist()}


def mesh_arrays(vertices: np.ndarray, faces: np.ndarray, decimals: int = 4) -> dict:
    """SPEC's JSON mesh as numpy arrays for :func:`json_bytes` (metres rounded to ``decimals``: 0.1 mm
    at 4); the same content as :func:`mesh_json` without building Python lists."""
    return {"vertices": np.round(np.asarray(vertices, np.float64), decimals),
            "faces": np.ascontiguousarray(faces, dtype=np.int32)}


def json_bytes(obj) -> bytes:
    """Compact JSON (UTF-8) of ``obj``, whose arrays and numbers may be numpy ones."""
    if orjson is not None:
        return orjson.dumps(obj, option=orjson.OPT_SERIALIZE_NUMPY)
    return json.dumps(obj, separators=(",", ":"),
                      default=lambda o: o.tolist() if isinstance(o, np.ndarray) else o.item()).encode()


def mesh_bytes(vertices: np.ndarray, faces: np.ndarray, file_type: str, colors: np.ndarray | None = None) -> bytes:
    """Encode a triangle mesh as ``glb`` or ``obj`` bytes (optional per-vertex RGBA uint8 colours)."""
    mesh = trimesh.Trimesh(vertices=np.asarray(vertices, float), faces=np.asarray(faces), process=False)
    if colors is not None:
        mesh.visual.vertex_colors = colors
    data = mesh.export(file_type=file_type)
    return data.encode() if isinstance(data, str) else data


def scene_bytes(nodes: list[tuple[str, np.ndarray, np.ndarray, np.ndarray | None]]) -> bytes:
    """GLB of several meshes, each a node of its own: ``(name, vertices (n, 3) m, faces (f, 3), RGBA uint8
    colours (n, 4) or None)``, in order."""
    scene = trimesh.Scene()
    for name, vertices, faces, colors in nodes:
        mesh = trimesh.Trimesh(vertices=np.asarray(vertices, float), faces=np.asarray(faces), process=False)
        if colors is not None:
            mesh.visual.vertex_colors = colors
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    return scene.export(file_type="glb")
