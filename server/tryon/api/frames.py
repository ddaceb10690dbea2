"""The WebSocket's binary frames: a 12-byte header (little-endian uint32 frame number, uint32 simulation
step, float32 seconds since the request) and the full mesh's vertex positions, as float32 metres or uint16
in a box around the body (``FrameCodec``). The protocol is in ``routes/ws.py`` and docs/live-tryon.md."""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

FRAME_HEADER = struct.Struct("<IIf")  # frame number, simulation step, seconds since the request
# A live session's body message (a pose update's body) is followed by one binary message of the body's vertices:
BODY_VERTEX_LAYOUT = "xyz per vertex, little-endian float32, metres, no header"

# m: how far beyond the body's bounding box quantized (uint16) positions reach; a garment hanging or
# sliding further is clamped to the box. 65,535 levels over a 1.8 m body + 2 x 0.25 m: 0.035 mm.
QUANT_MARGIN = 0.25


@dataclass(frozen=True)
class FrameCodec:
    """How vertex positions are written in a frame.

    ``float32``: x, y, z little-endian float32, metres (12 bytes per vertex).
    ``uint16``: x, y, z little-endian uint16 q, with position = origin + q * scale per axis (metres;
    6 bytes per vertex, resolution ``scale`` ~0.04 mm); positions outside the box are clamped to it.
    """

    type: str = "float32"
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)

    @classmethod
    def around(cls, type_: str, vertices: np.ndarray) -> "FrameCodec":
        """The codec ``type_``; for uint16 its box is ``vertices``' bounding box grown by QUANT_MARGIN."""
        if type_ == "float32":
            return cls()
        lo = vertices.min(axis=0) - QUANT_MARGIN
        hi = vertices.max(axis=0) + QUANT_MARGIN
        return cls("uint16", tuple(float(v) for v in lo), tuple(float(v) for v in (hi - lo) / 65535.0))

    @property
    def bytes_per_vertex(self) -> int:
        return 12 if self.type == "float32" else 6

    def encode(self, vertices: np.ndarray) -> bytes:
        """(n, 3) metres -> the frame's position bytes."""
        if self.type == "float32":
            return np.ascontiguousarray(vertices, dtype="<f4").tobytes()
        q = np.rint((vertices - np.asarray(self.origin)) / np.asarray(self.scale))
        return np.clip(q, 0, 65535).astype("<u2").tobytes()

    def decode(self, data: bytes) -> np.ndarray:
        """Inverse of :meth:`encode` (tests, Python clients): (n, 3) float64 metres."""
        if self.type == "float32":
            return np.frombuffer(data, dtype="<f4").reshape(-1, 3).astype(np.float64)
        q = np.frombuffer(data, dtype="<u2").reshape(-1, 3)
        return np.asarray(self.origin) + q * np.asarray(self.scale)

    def describe(self, vertex_count: int) -> dict:
        """The init message's ``encoding``."""
        out = {
            "type": self.type,
            "byte_order": "little",
            "header_bytes": FRAME_HEADER.size,
            "header": ["frame:uint32", "step:uint32", "time_s:float32"],
            "layout": "xyz per vertex, metres" if self.type == "float32"
                      else "xyz per vertex: position = origin + q * scale, metres",
            "components": 3,
            "bytes_per_frame": FRAME_HEADER.size + self.bytes_per_vertex * vertex_count,
        }
        if self.type == "uint16":
            out.update(origin=list(self.origin), scale=list(self.scale))
        return out


FLOAT32 = FrameCodec()


def encoding(vertex_count: int, codec: FrameCodec = FLOAT32) -> dict:
    """How a binary frame is laid out; sent in the init message."""
    return codec.describe(vertex_count)


def encode_positions(vertices: np.ndarray, codec: FrameCodec = FLOAT32) -> bytes:
    """(n, 3) positions as the codec's bytes (default little-endian float32 x, y, z per vertex)."""
    return codec.encode(vertices)


def encode_frame(frame: int, step: int, vertices: np.ndarray | bytes, time_s: float = 0.0,
                 codec: FrameCodec = FLOAT32) -> bytes:
    """One binary frame: header (frame number, step, seconds since the request) + positions."""
    payload = vertices if isinstance(vertices, bytes) else codec.encode(vertices)
    return FRAME_HEADER.pack(frame, max(int(step), 0), time_s) + payload


def frame_due(due: float, now: float, interval: float) -> float:
    """When the next frame may go (monotonic s), on a cadence of ``interval`` s: one interval after the last
    frame's slot ``due``, not after the moment it went (``now``), so a frame a few milliseconds late (a step
    that ended after its slot, a busy event loop) does not push every later frame back (spaced an interval
    after the last one sent, a live session dragging a slider got 28.9 frames a second at 30 fps); but never
    sooner than half an interval after ``now``: after a pause (a re-pose's set-up) the cadence starts again
    instead of sending two frames at once."""
    return max(due + interval, now + 0.5 * interval)
