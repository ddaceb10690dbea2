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


# glTF 2.0 constants (the specification's numbers): component types, buffer-view targets.
_FLOAT, _UBYTE, _UINT = 5126, 5121, 5125
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963


def morph_glb(meshes: list[tuple[str, list[np.ndarray], np.ndarray, np.ndarray | None]],
              seconds_per_pose: float = 1.0) -> bytes:
    """An animated GLB of meshes that change shape: each ``(name, positions, faces (f, 3), RGBA uint8 colours
    (n, 4) or None)``, ``positions`` a list of P (n, 3) arrays (metres), one per pose, the same topology.
    Each mesh is a node whose base shape is the first pose and whose morph targets are the displacements to
    the others (P - 1 targets); one animation ("motion") steps the targets' weights from pose to pose,
    ``seconds_per_pose`` apart, linearly. trimesh does not write morph targets, so the file is written here
    (glTF 2.0: a JSON chunk and one binary buffer)."""
    blob = bytearray()
    views, accessors = [], []

    def add(array: np.ndarray, component: int, kind: str, target: int | None, minmax: bool = False) -> int:
        data = np.ascontiguousarray(array)
        while len(blob) % 4:
            blob.append(0)
        view = {"buffer": 0, "byteOffset": len(blob), "byteLength": data.nbytes}
        if target is not None:
            view["target"] = target
        blob.extend(data.tobytes())
        views.append(view)
        accessor = {"bufferView": len(views) - 1, "componentType": component, "count": int(len(data)), "type": kind}
        if component == _UBYTE:
            accessor["normalized"] = True
        if minmax:
            accessor["min"] = data.min(axis=0).astype(float).tolist() if data.ndim > 1 else [float(data.min())]
            accessor["max"] = data.max(axis=0).astype(float).tolist() if data.ndim > 1 else [float(data.max())]
        accessors.append(accessor)
        return len(accessors) - 1

    gltf_meshes, nodes, channels, samplers = [], [], [], []
    poses = len(meshes[0][1])
    times = add(np.arange(poses, dtype=np.float32) * seconds_per_pose, _FLOAT, "SCALAR", None, minmax=True)
    for name, positions, faces, colours in meshes:
        base = np.asarray(positions[0], dtype=np.float32)
        attributes = {"POSITION": add(base, _FLOAT, "VEC3", _ARRAY_BUFFER, minmax=True)}
        if colours is not None:
            attributes["COLOR_0"] = add(np.asarray(colours, dtype=np.uint8), _UBYTE, "VEC4", _ARRAY_BUFFER)
        targets = [{"POSITION": add(np.asarray(p, dtype=np.float32) - base, _FLOAT, "VEC3", _ARRAY_BUFFER,
                                    minmax=True)} for p in positions[1:]]
        indices = add(np.asarray(faces, dtype=np.uint32).reshape(-1), _UINT, "SCALAR", _ELEMENT_ARRAY_BUFFER)
        gltf_meshes.append({"name": name, "primitives": [{"attributes": attributes, "indices": indices,
                                                           "targets": targets}],
                            "weights": [0.0] * len(targets), "extras": {"targetNames": [f"pose {i}" for i in
                                                                                        range(1, poses)]}})
        nodes.append({"name": name, "mesh": len(gltf_meshes) - 1})
        # weights per keyframe: pose 0 all zero, pose i one on target i - 1
        weights = np.zeros((poses, max(poses - 1, 1)), dtype=np.float32)[:, :poses - 1]
        for i in range(1, poses):
            weights[i, i - 1] = 1.0
        samplers.append({"input": times, "output": add(weights.reshape(-1), _FLOAT, "SCALAR", None),
                         "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": len(nodes) - 1, "path": "weights"}})
    document = {
        "asset": {"version": "2.0", "generator": "tryon"},
        "scene": 0, "scenes": [{"nodes": list(range(len(nodes)))}], "nodes": nodes, "meshes": gltf_meshes,
        "animations": [{"name": "motion", "channels": channels, "samplers": samplers}] if poses > 1 else [],
        "accessors": accessors, "bufferViews": views, "buffers": [{"byteLength": len(blob)}],
    }
    text = json.dumps(document, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    while len(blob) % 4:
        blob.append(0)
    total = 12 + 8 + len(text) + 8 + len(blob)
    out = bytearray()
    out += np.array([0x46546C67, 2, total], dtype="<u4").tobytes()  # "glTF", version 2, length
    out += np.array([len(text), 0x4E4F534A], dtype="<u4").tobytes() + text  # JSON chunk
    out += np.array([len(blob), 0x004E4942], dtype="<u4").tobytes() + bytes(blob)  # BIN chunk
    return bytes(out)
