"""Our engine on the peer scenes: ``tryon.sim.run.drape`` itself (Verlet, strain-limit passes, body
collision via the cylinder maps), timed frame by frame through its ``on_frame`` callback.

The peers run a fixed number of frames, so the rest stop is pushed past the last step; the ball is a body
of one part (an icosphere) built with ``build_part_maps``.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from tryon.bench.cloth_scene import FRAME_DT, HEIGHT, RADIUS, SIDE, FrameProbe

# Icosphere subdivisions of the ball mesh: level 3 (1280 faces, ~4.7 cm edges) sits within 1 mm of the
# true sphere, under the 4 mm collision margin, with ~8 faces per cylinder-map cell.
SPHERE_SUBDIVISIONS = 3
# Map margin of the ball body, m (as the synthetic bodies of tryon.bench.synthetic).
MAP_MARGIN = 0.01
# m: our scene is lifted by this much (and measured back in the shared frame): our simulation has a
# floor at y = 0 (a body's feet), which would cut the ball at its equator; the peers have none.
LIFT = 1.0


def sphere_body(radius: float = RADIUS, center=(0.0, 0.0, 0.0)):
    """A ``Body`` with a single part: an icosphere of ``radius`` metres at ``center``. The part's axis
    runs along x, so the ball's top (where the cloth lands) is far from the cylinder map's poles."""
    import trimesh

    from tryon.body.maps import build_part_maps
    from tryon.body.types import Body

    mesh = trimesh.creation.icosphere(subdivisions=SPHERE_SUBDIVISIONS, radius=radius)
    c = np.asarray(center, dtype=np.float64)
    v = np.ascontiguousarray(mesh.vertices + c, dtype=np.float64)
    f = np.ascontiguousarray(mesh.faces, dtype=np.int32)
    face_part = np.zeros(len(f), dtype=np.int16)
    axes = np.array([[[-radius, 0.0, 0.0], [radius, 0.0, 0.0]]]) + c
    return Body(
        vertices=v, faces=f, vertex_normals=np.asarray(mesh.vertex_normals, dtype=np.float64),
        face_normals=np.asarray(mesh.face_normals, dtype=np.float64), face_part=face_part, parts=("ball",),
        part_axes=axes, maps=build_part_maps(v, f, face_part, axes, MAP_MARGIN), requested={}, achieved={},
        levels={},
    )


def timed_drape(body, model, settings, initial=None, steps_per_frame: int = 1, probe=None,
                max_seconds: float = 1e9, tuning=None):
    """Run a drape (``start``, ``settle``) for exactly ``settings.max_steps`` steps (no rest stop), timing each
    frame of ``steps_per_frame`` steps between the ``on_frame`` callbacks (the probe's own time excluded); the
    start-up's steps too (``settle``'s ``start_up``: a try-on does not stream them, but it runs them).
    Returns (frame seconds list, TryOnResult)."""
    from tryon.sim.run import settle
    from tryon.sim.start import start
    from tryon.sim.tuning import TUNING

    settings = replace(settings, min_steps=settings.max_steps + 1)
    frames = []
    state = {"acc": 0.0, "last": None, "start": None}

    def on_frame(step, x):
        now = time.perf_counter()
        if state["last"] is None:
            state["start"] = now
        else:
            state["acc"] += now - state["last"]
        if step % steps_per_frame == 0 and state["last"] is not None:
            frames.append(state["acc"])
            state["acc"] = 0.0
            if probe is not None:
                probe(x)
        keep_going = now - state["start"] < max_seconds
        state["last"] = time.perf_counter()
        return keep_going

    result = settle(start(body, model, settings, tuning or TUNING, initial), on_frame, start_up=True)[0]
    return frames, result


def run_sphere(n: int, frames: int, settings=None, substeps: int = 1, max_seconds: float = 1e9, tuning=None) -> dict:
    """Our cloth-on-ball run: ``substeps`` time steps of FRAME_DT / substeps per frame (``tuning``: the method's
    knobs, default ``TUNING``)."""
    from tryon.bench.synthetic import cloth_square
    from tryon.sim.settings import SimSettings
    from tryon.sim.tuning import TUNING

    t0 = time.perf_counter()
    settings = settings or SimSettings()
    # one extra step: the first callback only starts the clock
    settings = replace(settings, time_step=FRAME_DT / substeps, max_steps=frames * substeps + 1)
    body = sphere_body(center=(0.0, LIFT, 0.0))
    # cloth_square orders vertices as meshgrid(x, z) (row = z); transpose to the scene's (i = x, j = z).
    model = cloth_square(size=SIDE, n=n, height=HEIGHT + LIFT)
    lift = np.array([0.0, LIFT, 0.0])
    order = np.arange(n * n).reshape(n, n).T.ravel()
    setup = time.perf_counter() - t0
    probe = FrameProbe(n)
    # the drape tests the body parts within ``part_reach`` of the garment's start: right for a garment put on
    # a body, too short for a cloth dropped from above a ball
    tuning = tuning or TUNING
    # nor do the peers' ball examples untangle the cloth's crossings of itself (``collision/untangle.py``): the
    # ball compares the solvers alone
    tuning = replace(tuning, part_reach=max(tuning.part_reach, HEIGHT), untangle_step=0.0)
    times, result = timed_drape(body, model, settings, initial=model.vertices.copy(), steps_per_frame=substeps,
                                probe=lambda x: probe(x[order] - lift), max_seconds=max_seconds, tuning=tuning)
    out = probe.summary(times)
    # what a try-on answers: the last frame relaxed (``sim/relax.py``), the figures a caller gets
    answer = FrameProbe(n)
    answer(result.coarse[order] - lift)
    out["answer_stretch"] = answer.final_stretch
    out["answer_penetration_mm"] = answer.final_penetration * 1e3
    out.update({
        "engine": "ours", "method": "Verlet + strain-limit passes + cylinder-map collision", "particles": n * n,
        "substeps": substeps, "setup_s": setup,
        "params": {"time_step": settings.time_step, "passes": settings.passes,
                   "strain_limit": list(settings.strain_limit),
                   "collision_margin": settings.collision_margin, "threads": 1, "precision": "f64"},
    })
    return out
