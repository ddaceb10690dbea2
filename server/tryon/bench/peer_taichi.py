"""Peer engine: Taichi's classic mass-spring cloth on a ball, CPU backend (run as a subprocess).

The physics is Taichi's own example (``examples/ggui_examples/mass_spring_3d_ggui.py``): explicit
(symplectic Euler) springs to the second ring of neighbours with Young's modulus 3e4 and dashpot damping
1e4, exponential air drag 1/s, the ball as a velocity projection, and the example's time step
dt = 4e-2 / n with floor(frame / dt) substeps per frame (n >= 100; see ``run`` for coarser cloths).
Only the scene size is ours (``cloth_scene``).

``python -m tryon.bench.peer_taichi N FRAMES MAX_SECONDS [THREADS]`` prints one JSON line with the figures of
``cloth_scene``; THREADS caps Taichi's CPU threads (default: all cores).
"""

from __future__ import annotations

import json
import sys
import time


from tryon.bench.cloth_scene import FRAME_DT, HEIGHT, RADIUS, SIDE, FrameProbe


def run(n: int, frames: int, max_seconds: float = 1e9, threads: int | None = None) -> dict:
    import taichi as ti

    extra = {} if threads is None else {"cpu_max_num_threads": int(threads)}
    ti.init(arch=ti.cpu, log_level=ti.WARN, offline_cache=True, **extra)
    quad = SIDE / (n - 1)
    # The example's step is 4e-2 / n (s), tuned at n = 128; below n ~ 100 its dashpot term (1e4 x quad per
    # spring, unit masses) is no longer stable with that step, so coarser cloths use n = 100's step.
    dt = 4e-2 / max(n, 100)
    substeps = int(FRAME_DT // dt)
    spring_y, dashpot, drag = 3e4, 1e4, 1.0  # the example's constants
    offsets = [ti.Vector([i, j]) for i in range(-2, 3) for j in range(-2, 3)
               if (i, j) != (0, 0) and abs(i) + abs(j) <= 2]

    @ti.data_oriented
    class Cloth:
        def __init__(self):
            self.x = ti.Vector.field(3, dtype=ti.f32, shape=(n, n))
            self.v = ti.Vector.field(3, dtype=ti.f32, shape=(n, n))

        @ti.kernel
        def init(self):
            for i, j in self.x:
                self.x[i, j] = [i * quad - SIDE / 2, HEIGHT, j * quad - SIDE / 2]
                self.v[i, j] = [0, 0, 0]

        @ti.kernel
        def substep(self):
            for i in ti.grouped(self.x):
                self.v[i] += ti.Vector([0.0, -9.8, 0.0]) * dt
            for i in ti.grouped(self.x):
                force = ti.Vector([0.0, 0.0, 0.0])
                for so in ti.static(offsets):
                    j = i + so
                    if 0 <= j[0] < n and 0 <= j[1] < n:
                        x_ij = self.x[i] - self.x[j]
                        v_ij = self.v[i] - self.v[j]
                        d = x_ij.normalized()
                        cur = x_ij.norm()
                        orig = quad * float(i - j).norm()
                        force += -spring_y * d * (cur / orig - 1)
                        force += -v_ij.dot(d) * d * dashpot * quad
                self.v[i] += force * dt
            for i in ti.grouped(self.x):
                self.v[i] *= ti.exp(-drag * dt)
                off = self.x[i]
                if off.norm() <= RADIUS:
                    nrm = off.normalized()
                    self.v[i] -= ti.min(self.v[i].dot(nrm), 0) * nrm
                self.x[i] += dt * self.v[i]

    t0 = time.perf_counter()
    cloth = Cloth()
    cloth.init()
    probe = FrameProbe(n)
    times = []
    setup = time.perf_counter() - t0
    start = time.perf_counter()
    for _ in range(frames):
        if times and time.perf_counter() - start > max_seconds:
            break  # out of wall-time budget: the figures cover the frames run
        t = time.perf_counter()
        for _ in range(substeps):
            cloth.substep()
        ti.sync()
        times.append(time.perf_counter() - t)
        probe(cloth.x.to_numpy().reshape(-1, 3))
    out = probe.summary(times)
    out.update({
        "engine": "taichi", "version": ".".join(map(str, ti.__version__)), "method": "explicit mass-spring",
        "particles": n * n, "substeps": substeps, "setup_s": setup,
        "params": {"dt": dt, "spring_Y": spring_y, "dashpot_damping": dashpot, "drag": drag,
                   "threads": threads or "taichi default (all cores)", "precision": "f32"},
    })
    return out


if __name__ == "__main__":
    result = run(int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3]),
                 int(sys.argv[4]) if len(sys.argv) > 4 else None)
    print(json.dumps(result))
