"""The classic cloth-on-a-sphere scene shared by every engine in the peer comparison.

A square cloth ``SIDE`` metres wide, ``n x n`` particles, starts flat at y = ``HEIGHT`` above a fixed
sphere of radius ``RADIUS`` at the origin and falls under gravity for ``FRAMES`` frames of ``FRAME_DT``
seconds (Taichi's cloth-on-ball example: 1 m cloth at y = 0.6 over a 0.3 m ball). This module imports
only numpy so the peer engines' subprocesses can use it without loading our simulation.
"""

from __future__ import annotations

import numpy as np

SIDE = 1.0  # m, cloth width (Taichi example)
HEIGHT = 0.6  # m, initial height of the flat cloth (Taichi example)
RADIUS = 0.3  # m, sphere radius (Taichi example)
FRAME_DT = 1.0 / 60.0  # s, one display frame
FRAMES = 300  # frames simulated per run (5 s: the fall, the contact and the settling)
WARMUP_FRAMES = 10  # frames left out of the timing median (JIT, caches, first contacts)
DENSITY = 0.15  # kg/m^2, areal density of a light shirt fabric (the garment stage's default order)
SIZES = (32, 64, 100, 200)  # particles per side: 1k, 4k, 10k, 40k particles


def grid_positions(n: int) -> np.ndarray:
    """(n * n, 3) initial particle positions, row-major over (i, j) with x = i, z = j."""
    u = np.linspace(-SIDE / 2, SIDE / 2, n)
    xx, zz = np.meshgrid(u, u, indexing="ij")
    return np.stack([xx.ravel(), np.full(n * n, HEIGHT), zz.ravel()], axis=1)


def grid_edges(n: int) -> np.ndarray:
    """(e, 2) int64 structural edges (grid neighbours along i and along j) of the row-major n x n grid."""
    idx = np.arange(n * n).reshape(n, n)
    a = np.stack([idx[:-1].ravel(), idx[1:].ravel()], axis=1)
    b = np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()], axis=1)
    return np.vstack([a, b]).astype(np.int64)


def outcome(final: np.ndarray) -> str:
    """How a run ended: 'non-finite', 'thrown up' (some particle above the start height: energy came from
    nowhere), 'on the ball' (a particle within 2 cm of its surface), or 'slid off'."""
    if not np.isfinite(final).all():
        return "non-finite"
    if final[:, 1].max() > HEIGHT + 0.05:
        return "thrown up"
    r = np.sqrt(np.einsum("ij,ij->i", final, final))
    return "on the ball" if r.min() < RADIUS + 0.02 else "slid off"


class FrameProbe:
    """Accumulates the scene's accuracy figures over frames (called outside the timed region).

    max_stretch: largest structural edge length / rest - 1 over all frames (rest = SIDE / (n - 1));
    final_stretch: the same at the last frame.
    max_penetration_mm: deepest particle inside the sphere over all frames, mm (0 if never inside);
    final_penetration: the same at the last frame.
    """

    def __init__(self, n: int):
        self.edges = grid_edges(n)
        self.rest = SIDE / (n - 1)
        self.max_stretch = 0.0
        self.max_penetration = 0.0
        self.final = None
        self.final_stretch = 0.0
        self.final_penetration = 0.0

    def __call__(self, x: np.ndarray) -> None:
        x = np.asarray(x, dtype=np.float64).reshape(-1, 3)
        d = x[self.edges[:, 0]] - x[self.edges[:, 1]]
        stretch = np.sqrt(np.einsum("ij,ij->i", d, d)).max() / self.rest - 1.0
        depth = RADIUS - np.sqrt(np.einsum("ij,ij->i", x, x)).min()
        self.max_stretch = max(self.max_stretch, float(stretch))
        self.final_stretch = float(stretch)
        self.max_penetration = max(self.max_penetration, float(depth))
        self.final_penetration = max(0.0, float(depth))
        self.final = x

    def summary(self, frame_seconds: list[float]) -> dict:
        """Figures of a finished run; ``frame_seconds`` wall time of each frame (s)."""
        ft = np.asarray(frame_seconds[WARMUP_FRAMES:] or frame_seconds, dtype=np.float64)
        final = self.final
        r = np.sqrt(np.einsum("ij,ij->i", final, final))
        return {
            "frame_ms_median": float(np.median(ft) * 1e3),
            "frame_ms_mean": float(ft.mean() * 1e3),
            "first_frame_ms": float(frame_seconds[0] * 1e3),
            "frames": len(frame_seconds),
            "max_stretch": self.max_stretch,
            "final_stretch": self.final_stretch,
            "max_penetration_mm": self.max_penetration * 1e3,
            "final_penetration_mm": self.final_penetration * 1e3,
            # the cloth still lies on the ball when some particle is within 2 cm of its surface
            "on_sphere_at_end": bool(r.min() < RADIUS + 0.02),
            "final_lowest_y": float(final[:, 1].min()),
            "finite": bool(np.isfinite(final).all()),
            "outcome": outcome(final),
        }
