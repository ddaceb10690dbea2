"""Mesh encodings for responses: JSON (SPEC section 6), GLB, OBJ."""

from __future__ import annotations

import numpy as np
import trimesh

MEDIA_TYPES = {"json": "application/json", "glb": "model/gltf-binary", "obj": "text/plain"}


def mesh_json(vertices: np.ndarray, faces: np.ndarray, decimals: int = 5) -> dict:
    """``{"vertices": [[x, y, z], ...], "faces": [[i, j, k], ...]}``; metres rounded to ``decimals``."""
    return {"vertices": np.round(vertices, decimals).tolist(), "faces": np.asarray(faces).tolist()}


def mesh_bytes(vertices: np.ndarray, faces: np.ndarray, file_type: str, colors: np.ndarray | None = None) -> bytes:
    """Encode a triangle mesh as ``glb`` or ``obj`` bytes (optional per-vertex RGBA uint8 colours)."""
    mesh = trimesh.Trimesh(vertices=np.asarray(vertices, float), faces=np.asarray(faces), process=False)
    if colors is not None:
        mesh.visual.vertex_colors = colors
    data = mesh.export(file_type=file_type)
    return data.encode() if isinstance(data, str) else data
