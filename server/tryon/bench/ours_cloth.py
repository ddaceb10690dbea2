"""Our engine on the peer scenes: the same step as ``tryon.sim.run.drape`` (Verlet, strain-limit passes,
body collision via the cylinder maps), driven frame by frame.

``drape`` itself is not used for the cloth-on-ball scene: it only tests the body parts within reach of
the aligned garment (the ball is 30 cm below the cloth) and stops at rest, while the peers run a fixed
number of frames. The ball is a body of one part (an icosphere), built with ``build_part_maps``.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from tryon.bench.cloth_scene import FRAME_DT, HEIGHT, RADIUS, SIDE, FrameProbe

# Icosphere subdivisions of the ball mesh: level 3 (1280 faces, ~4.7 cm edges) sits within 1 mm of the
# true sphere, under the 4 mm collision margin, with ~8 faces per cylinder-map cell.
SPHERE_SUBDIVISIONS = 3
# Map margin of the ball body, m (as the synthetic bodies of tryon.sim.scenes).
MAP_MARGIN = 0.01


def sphere_body(radius: float = RADIUS):
    """A ``Body`` with a single part: an icosphere of ``radius`` metres at the origin. The part's axis
    runs along x, so the ball's top (where the cloth lands) is far from the cylinder map's poles."""
    import trimesh

    from tryon.body.maps import build_part_maps
    from tryon.body.types import Body

    mesh = trimesh.creation.icosphere(subdivisions=SPHERE_SUBDIVISIONS, radius=radius)
    v = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    f = np.ascontiguousarray(mesh.faces, dtype=np.int32)
    face_part = np.zeros(len(f), dtype=np.int16)
    axes = np.array([[[-radius, 0.0, 0.0], [radius, 0.0, 0.0]]])
    return Body(
        vertices=v, faces=f, vertex_normals=np.asarray(mesh.vertex_normals, dtype=np.float64),
        face_normals=np.asarray(mesh.face_normals, dtype=np.float64), face_part=face_part, parts=("ball",),
        part_axes=axes, maps=build_part_maps(v, f, face_part, axes, MAP_MARGIN), requested={}, achieved={},
        levels={},
    )


class Stepper:
    """The simulation step of ``drape`` on given state arrays; ``step()`` advances one time step."""

    def __init__(self, body, model, settings, x0: np.ndarray | None = None):
        from tryon.sim.bodystate import BodyCollider

        self.s = settings
        self.x = np.array(model.coarse_vertices if x0 is None else x0, dtype=np.float64)
        self.x_prev = self.x.copy()
        self.x_checked = self.x.copy()
        mass = np.ascontiguousarray(model.mass, dtype=np.float64)
        self.mass = mass
        self.inv_mass = np.where(mass > 0, 1.0 / np.where(mass > 0, mass, 1.0), 0.0)
        self.springs = np.ascontiguousarray(model.springs, dtype=np.int64)
        self.rest = np.ascontiguousarray(model.rest, dtype=np.float64)
        self.kind = np.ascontiguousarray(model.kind, dtype=np.int64)
        self.limits = settings.limits_array()
        self.compression = settings.compression_array()
        self.collider = BodyCollider(body, settings.collision_margin)
        self.parts = np.arange(len(body.parts), dtype=np.int64)
        self.contact = np.zeros(len(self.x), dtype=np.bool_)
        self.active = np.ones(len(self.x), dtype=np.bool_)

    def step(self, dt: float | None = None) -> None:
        from tryon.sim.constraints import satisfy_springs
        from tryon.sim.integrate import verlet_step

        s = self.s
        dt = s.time_step if dt is None else dt
        verlet_step(self.x, self.x_prev, self.inv_mass, dt, s.gravity, s.air_drag, s.max_speed)
        satisfy_springs(self.x, self.inv_mass, self.springs, self.rest, self.kind, self.limits, self.compression,
                        s.passes)
        d = self.x - self.x_checked
        moved = np.einsum("ij,ij->i", d, d) > 1e-8  # (1e-4 m)^2, drape's REST_MOVE
        np.logical_or(moved, self.contact, out=self.active)
        self.collider.collide(self.x, self.x_prev, self.inv_mass, self.active, self.parts, s.contact_offset,
                              s.friction, self.contact)
        self.x_checked[self.active] = self.x[self.active]

    def collide_all(self, x: np.ndarray) -> None:
        """Collision test of every point of ``x`` (the per-step collision-detection cost, all active)."""
        active = np.ones(len(x), dtype=np.bool_)
        contact = np.zeros(len(x), dtype=np.bool_)
        inv = np.ones(len(x))
        self.collider.collide(x, x.copy(), inv, active, self.parts, self.s.contact_offset, 0.0, contact)


def run_sphere(n: int, frames: int, settings=None, substeps: int = 1, max_seconds: float = 1e9) -> dict:
    """Our cloth-on-ball run: ``substeps`` time steps of FRAME_DT / substeps per frame."""
    from tryon.sim.scenes import cloth_square
    from tryon.sim.settings import SimSettings

    t0 = time.perf_counter()
    settings = settings or SimSettings()
    settings = replace(settings, time_step=FRAME_DT / substeps)
    body = sphere_body()
    # cloth_square orders vertices as meshgrid(x, z) (row = z); transpose to the scene's (i = x, j = z).
    model = cloth_square(size=SIDE, n=n, height=HEIGHT)
    order = np.arange(n * n).reshape(n, n).T.ravel()
    stepper = Stepper(body, model, settings)
    setup = time.perf_counter() - t0
    probe = FrameProbe(n)
    times = []
    start = time.perf_counter()
    for _ in range(frames):
        if times and time.perf_counter() - start > max_seconds:
            break
        t = time.perf_counter()
        for _ in range(substeps):
            stepper.step()
        times.append(time.perf_counter() - t)
        probe(stepper.x[order])
    out = probe.summary(times)
    out.update({
        "engine": "ours", "method": "Verlet + strain-limit passes + cylinder-map collision", "particles": n * n,
        "substeps": substeps, "setup_s": setup,
        "params": {"time_step": settings.time_step, "passes": settings.passes,
                   "strain_limit": list(settings.strain_limit), "friction": settings.friction,
                   "collision_margin": settings.collision_margin, "threads": 1, "precision": "f64"},
    })
    return out
