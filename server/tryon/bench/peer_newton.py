"""Peer engine: Newton (NVIDIA Warp's successor to ``warp.sim``) XPBD or VBD cloth, CPU device (subprocess).

Set up as Newton's own cloth examples do (``newton/examples/cloth/example_cloth_hanging.py``, XPBD
variant): ``ModelBuilder.add_cloth_grid`` with ``add_springs=True``, ``SolverXPBD(iterations=10)``, 10
substeps per 1/60 s frame, the collision pipeline run every substep, the frame captured as a Warp graph.
Departures, so that the scene is the same as the other engines': y up, and a particle radius equal to
our collision margin (4 mm) instead of 5 cm. The example's 0.1 kg per particle and spring stiffness are
kept: with a light fabric's mass (0.15 kg/m^2) or springs 100x stiffer the XPBD cloth blew up on this
scene (measured), so the peer runs in the regime its authors tuned.

VBD (Vertex Block Descent, Chen et al. 2024: per-vertex Newton steps over graph colours, the fastest converging
solver published for cloth) is set up as the same example's VBD variant: triangle (StVK) elasticity
``tri_ke = tri_ka = 1e3``, damping ``tri_kd = 1e2``, the particles coloured (``builder.color``), contact
stiffness and damping 1e2, 10 iterations per substep; self-contact off (the ball scene has none).

``python -m tryon.bench.peer_newton SCENE N FRAMES MAX_SECONDS [xpbd|vbd]`` prints one JSON line; SCENE is
``sphere`` (the cloth-on-ball scene, N particles per side) or a path to an ``.npz`` with a garment-on-body scene
(``cloth_vertices``, ``cloth_faces``, ``body_vertices``, ``body_faces``, ``edges``, ``rest``; N unused; XPBD).
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np

from tryon.bench.cloth_scene import FRAME_DT, HEIGHT, RADIUS, SIDE, FrameProbe

SUBSTEPS = 10  # per frame, as the example
ITERATIONS = 10  # XPBD iterations per substep, as the example
SPRING_KE = 1.0e3  # the example's spring stiffness (XPBD compliance = 1 / ke)
SPRING_KD = 1.0  # the example's spring damping
PARTICLE_RADIUS = 0.004  # m: contact thickness, equal to our collision margin
CONTACT_MU = 1.0  # the example's soft-contact friction
PARTICLE_MASS = 0.1  # kg, the example's particle mass
VBD_TRI_KE = 1.0e3  # the VBD example's triangle stretch stiffness (and tri_ka, its area stiffness)
VBD_TRI_KD = 1.0e2  # the VBD example's triangle damping
VBD_CONTACT_KE = 1.0e2  # the VBD example's soft-contact stiffness and damping


def _solver_loop(model, wp, newton, method: str = "xpbd"):
    if method == "vbd":
        solver = newton.solvers.SolverVBD(model, iterations=ITERATIONS, particle_enable_self_contact=False)
    else:
        solver = newton.solvers.SolverXPBD(model, iterations=ITERATIONS)
    state = [model.state(), model.state()]
    control = model.control()
    pipeline = newton.CollisionPipeline(model)
    contacts = pipeline.contacts()
    dt = FRAME_DT / SUBSTEPS

    def simulate():
        for _ in range(SUBSTEPS):
            state[0].clear_forces()
            pipeline.collide(state[0], contacts)
            solver.step(state[0], state[1], control, contacts, dt)
            state[0], state[1] = state[1], state[0]

    # SUBSTEPS is even, so the graph's reads and writes line up with state[0] after each replay.
    with wp.ScopedCapture() as capture:
        simulate()
    graph = capture.graph

    def frame():
        wp.capture_launch(graph)
        wp.synchronize()

    return frame, state


def _finish(frame, state, probe, frames, max_seconds) -> list[float]:
    """Run up to ``frames`` frames (fewer if ``max_seconds`` of wall time run out); per-frame seconds."""
    times = []
    start = time.perf_counter()
    for _ in range(frames):
        if times and time.perf_counter() - start > max_seconds:
            break
        t = time.perf_counter()
        frame()
        times.append(time.perf_counter() - t)
        probe(state[0].particle_q.numpy())
    return times


def run_sphere(n: int, frames: int, max_seconds: float = 1e9, method: str = "xpbd") -> dict:
    import warp as wp

    wp.config.quiet = True
    import newton

    t0 = time.perf_counter()
    with wp.ScopedDevice("cpu"):
        builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=(0.0, -9.81, 0.0))
        cell = SIDE / (n - 1)
        # The grid spans local x, y; turning it by -90 degrees about x lays local y along world z.
        material = (dict(tri_ke=VBD_TRI_KE, tri_ka=VBD_TRI_KE, tri_kd=VBD_TRI_KD) if method == "vbd" else
                    dict(add_springs=True, spring_ke=SPRING_KE, spring_kd=SPRING_KD))
        builder.add_cloth_grid(
            pos=wp.vec3(-SIDE / 2, HEIGHT, SIDE / 2), rot=wp.quat_from_axis_angle(wp.vec3(1.0, 0.0, 0.0), -wp.pi * 0.5),
            vel=wp.vec3(0.0, 0.0, 0.0), dim_x=n - 1, dim_y=n - 1, cell_x=cell, cell_y=cell,
            mass=PARTICLE_MASS, edge_ke=1.0e1, edge_kd=0.0, particle_radius=PARTICLE_RADIUS, **material,
        )
        builder.add_shape_sphere(-1, xform=wp.transform(wp.vec3(0.0, 0.0, 0.0), wp.quat_identity()), radius=RADIUS)
        if method == "vbd":
            builder.color(include_bending=True)
        model = builder.finalize()
        model.soft_contact_mu = CONTACT_MU
        if method == "vbd":
            model.soft_contact_ke = VBD_CONTACT_KE
            model.soft_contact_kd = VBD_CONTACT_KE
        frame, state = _solver_loop(model, wp, newton, method)
        setup = time.perf_counter() - t0
        # Newton orders the grid with x fastest (index j * n + i); reorder to our row-major (i, j).
        order = np.arange(n * n).reshape(n, n).T.ravel()
        probe_inner = FrameProbe(n)

        def probe(q):
            probe_inner(np.asarray(q)[order])

        times = _finish(frame, state, probe, frames, max_seconds)
    out = probe_inner.summary(times)
    out.update({
        "engine": f"newton {method}", "version": newton.__version__,
        "method": "VBD (SolverVBD)" if method == "vbd" else "XPBD (SolverXPBD)", "particles": n * n,
        "substeps": SUBSTEPS, "setup_s": setup,
        "params": {"iterations": ITERATIONS, **({"tri_ke": VBD_TRI_KE, "tri_kd": VBD_TRI_KD} if method == "vbd" else
                                              {"spring_ke": SPRING_KE, "spring_kd": SPRING_KD}),
                   "particle_mass": PARTICLE_MASS, "particle_radius": PARTICLE_RADIUS, "mu": CONTACT_MU,
                   "device": "cpu", "precision": "f32"},
    })
    return out


def run_garment(path: str, frames: int, max_seconds: float = 1e9) -> dict:
    """Garment on body: the garment's coarse mesh as a cloth (springs = its edges), the body as a static
    triangle-mesh collider. Stretch is measured on the given ``edges`` / ``rest``; penetration is left
    to the caller (it has the body's inside test)."""
    import warp as wp

    wp.config.quiet = True
    import newton

    scene = np.load(path)
    cv, cf = scene["cloth_vertices"], scene["cloth_faces"]
    bv, bf = scene["body_vertices"], scene["body_faces"]
    edges, rest = scene["edges"], scene["rest"]
    # the garment's own mass (kg) if the scene gives it, else the example's 0.1 kg per particle
    cloth_mass = float(scene["mass"]) if "mass" in scene else PARTICLE_MASS * len(cv)
    t0 = time.perf_counter()
    with wp.ScopedDevice("cpu"):
        builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=(0.0, -9.81, 0.0))
        area = 0.5 * np.linalg.norm(np.cross(cv[cf[:, 1]] - cv[cf[:, 0]], cv[cf[:, 2]] - cv[cf[:, 0]]), axis=1).sum()
        builder.add_cloth_mesh(
            pos=wp.vec3(0.0, 0.0, 0.0), rot=wp.quat_identity(), scale=1.0, vel=wp.vec3(0.0, 0.0, 0.0),
            vertices=[wp.vec3(*p) for p in cv], indices=cf.ravel().tolist(), density=cloth_mass / area,
            add_springs=True, spring_ke=SPRING_KE, spring_kd=SPRING_KD, edge_ke=1.0e1, edge_kd=0.0,
            particle_radius=PARTICLE_RADIUS,
        )
        mesh = newton.Mesh(bv.astype(np.float32), bf.astype(np.int32).ravel())
        builder.add_shape_mesh(-1, mesh=mesh)
        model = builder.finalize()
        model.soft_contact_mu = CONTACT_MU
        frame, state = _solver_loop(model, wp, newton)
        setup = time.perf_counter() - t0
        stretch = [0.0]
        finals = [None]

        def probe(q):
            q = np.asarray(q, dtype=np.float64)
            d = np.linalg.norm(q[edges[:, 0]] - q[edges[:, 1]], axis=1)
            stretch[0] = max(stretch[0], float((d / rest - 1.0).max()))
            finals[0] = q

        times = _finish(frame, state, probe, frames, max_seconds)
    ft = np.asarray(times[10:] or times)
    np.save(path.replace(".npz", "_final.npy"), finals[0])
    return {
        "engine": "newton", "version": newton.__version__, "method": "XPBD (SolverXPBD), mesh collider",
        "particles": int(len(cv)), "substeps": SUBSTEPS, "setup_s": setup, "frames": len(times),
        "frame_ms_median": float(np.median(ft) * 1e3), "frame_ms_mean": float(ft.mean() * 1e3),
        "max_stretch": stretch[0], "finite": bool(np.isfinite(finals[0]).all()), "cloth_mass_kg": cloth_mass,
    }


if __name__ == "__main__":
    scene_arg, n_arg, frames_arg, budget = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])
    if scene_arg == "sphere":
        result = run_sphere(n_arg, frames_arg, budget, sys.argv[5] if len(sys.argv) > 5 else "xpbd")
    else:
        result = run_garment(scene_arg, frames_arg, budget)
    print(json.dumps(result))
