"""Speed of one try-on, phase by phase (issue 5: about 1 ms per step for a 7,500-vertex garment simulated
on its 30 % coarse mesh, a drape to rest well under a second).

``perf()`` builds a T-shirt of about 7,500 vertices with the catalogue generator (a finer grid
than the catalogue's own), prepares it at B = 0.3 (~2,250 particles), drapes it on a medium body and
times every kernel of the loop. Run ``python3 -m tryon.bench.perf``.

``finish_step`` runs 15 of a step's 16 substeps in one call; ``finish_step_ms_near_rest`` splits one such
call, ten steps before rest, into what its spring passes, contact passes and top-down sweep add (on a
quiet machine at 0af09b0: whole 4.9 ms = passes 2.2 + contact passes 1.5 + sweep 1.1 + tail 0.4), and
``spring_visits`` counts the springs such a step visits: at 1215040 16 substeps x (16,938 springs + 5,086 on
the body + 10,068 hanging) = 513,472, at ~9 ns each. A step of about 1 ms would need ~2 ns a visit or
about a fifth of the visits: a pass over the springs that only reads them (no writes, no branch on the
result) already costs ~5 ns a spring here, and fewer substeps (8 or 4, as many passes) took more steps to
rest and left waistbands over their limits on the small and medium bodies (the 90 catalogue drapes: 8 x 1
pass, 398 springs over and 21 % more steps, about the same wall time; 4 x 1, 803 over, twice the steps).

A faster pass does not get there either (one captured near-rest step, variants interleaved, medians): the
pass costs 6.6 ns a spring and a scan that only finds the springs outside their range 1.8 ns; scanning,
then correcting only those (about a fifth) made a whole step 10 % faster; a colour-ordered Jacobi pass
written to vectorise (no two springs of a colour share a point) was 2x slower (a square root and a division
for every spring); positions padded to (k, 4) changed nothing. At the scan's 1.8 ns, a step's 513,472 visits
alone would cost 0.9 ms, the collision another 0.7 ms. Once every spring near its length was elastic (13.9 ns a
visit), ordering the springs so that neighbours in a pass share no point (87 % do in the garment's order, each
correction waiting for the one before it) made the pass 7.6 ns, but moved the drapes the tests pin
(``docs/limits.md``: measured, not kept).
"""

from __future__ import annotations

import inspect
import json
import math
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from tryon.body.build import build_body
from tryon.body.params import Measurements, Pose
from tryon.garment import generate
from tryon.garment.catalogue import Catalogue
from tryon.sim.collision.collider import BodyCollider
from tryon.sim import step as step_module
from tryon.sim.finish import finish
from tryon.sim.relax import relax
from tryon.sim.run import drape
from tryon.sim.settings import SimSettings
from tryon.sim.start import start
from tryon.sim.step import step_drape
from tryon.sim.substeps import finish_step

# Grid spacing (m) that gives the generator's T-shirt (size M) about 7,500 vertices.
FINE_SPACING = 0.0106
# The body the perf T-shirt is draped on, cm.
PERF_BODY = dict(height=170, chest=96, waist=82, hips=100)


def fine_garment(data_dir: Path, kind: str = "tshirt", size: str = "M", spacing: float = FINE_SPACING,
                 simplification: float = 0.3):
    """A catalogue-style garment generated on a finer grid, prepared at ``simplification``."""
    saved = generate.SPACING
    generate.SPACING = spacing
    try:
        mesh = generate.garment_mesh(kind, size)
    finally:
        generate.SPACING = saved
    name, category = generate.GARMENTS[kind]
    text = generate.obj_text(mesh, f"{name} {size}, fine")
    catalogue = Catalogue(data_dir)
    meta = catalogue.ingest(text.encode(), name=f"{name} {size} fine", category=category, units="m",
                            filename=f"{kind}-{size.lower()}-fine.obj", simplify=simplification)
    return catalogue.model(meta.id)


class _Timer:
    """Wraps the kernels a step calls (``tryon.sim.step``'s names for them) and the body collision, and sums
    their wall time: a profiler of one loop, put back on exit."""

    # finish_step: the first substep's tail (sweep, planes, friction, floor) and the other substeps whole
    NAMES = ("verlet_step", "solve_listed", "finish_step", "reuse_planes", "points_to_test", "contact_springs",
             "sweep_springs", "top_down_order", "pack_sweep", "cap_stretch", "kinetic_energy_per_kg")

    def __init__(self, capture_step: int = 0):
        self.totals = {}
        self.saved = {}
        self.capture_step = capture_step  # finish_step's arguments at this step are kept (``captured``)
        self.captured = None
        self.calls = 0

    def __enter__(self):
        for name in self.NAMES:
            fn = getattr(step_module, name)
            self.saved[name] = fn
            setattr(step_module, name, self._wrap(name, fn))
        self.saved_collide = BodyCollider.collide
        timer = self

        def collide(this, *args, **kwargs):
            t = time.perf_counter()
            out = timer.saved_collide(this, *args, **kwargs)
            timer.totals["collide"] = timer.totals.get("collide", 0.0) + time.perf_counter() - t
            return out

        BodyCollider.collide = collide
        return self

    def _wrap(self, name, fn):
        def timed(*args, **kwargs):
            if name == "finish_step":
                self.calls += 1
                if self.calls == self.capture_step:
                    self.captured = [_copied(a) for a in args]
            t = time.perf_counter()
            out = fn(*args, **kwargs)
            self.totals[name] = self.totals.get(name, 0.0) + time.perf_counter() - t
            return out
        return timed

    def __exit__(self, *exc):
        for name, fn in self.saved.items():
            setattr(step_module, name, fn)
        BodyCollider.collide = self.saved_collide


def _copied(a):
    """A copy of one of finish_step's arguments that the drape goes on changing (arrays, and the arrays of
    a named tuple such as ``Movers``)."""
    if hasattr(a, "copy"):
        return a.copy()
    if isinstance(a, tuple) and hasattr(a, "_fields"):
        return type(a)(*[f.copy() if isinstance(f, np.ndarray) else f for f in a])
    return a


# the fields of finish_step's ``run`` (``Substeps``) that switch its parts off (see ``finish_step_split``)
_FINISH_PARTS = {"passes": {"per_sub": 0}, "contact_passes": {"contact_passes": 0}, "sweep": {"sweep": False}}


def finish_step_arguments(args: list) -> dict:
    """``finish_step``'s positional ``args`` by parameter name (in its order)."""
    return dict(zip(inspect.signature(finish_step.py_func).parameters, args))


def finish_step_split(args: list, repeats: int = 15) -> dict:
    """What each part of ``finish_step`` costs on one captured step (its positional ``args``), ms: the
    whole call, and the time each of the spring passes, the contact passes and the top-down sweep adds
    (the call without it, subtracted from the whole; median of ``repeats``); the rest is the tail (Verlet,
    planes, friction, floor)."""
    def timed(movers=None, **off) -> float:
        call = finish_step_arguments([_copied(a) for a in args])
        call["run"] = call["run"]._replace(**off)
        if movers is not None:
            call["movers"] = movers
        t = time.perf_counter()
        finish_step(*call.values())
        return time.perf_counter() - t

    timed()
    whole = statistics.median(timed() for _ in range(repeats))
    out = {"whole": round(1000 * whole, 3)}
    parts = dict(_FINISH_PARTS)
    # the within-step collision of points that moved far (``collision.movers``): off = an infinite reach
    parts["movers"] = {"movers": finish_step_arguments(args)["movers"]._replace(reach=math.inf)}
    for part, off in parts.items():
        out[part] = round(1000 * (whole - statistics.median(timed(**off) for _ in range(repeats))), 3)
    return out


def spring_visits(args: list, passed: int = 0) -> dict:
    """How many springs one step visits, from ``finish_step``'s positional ``args`` on a captured step:
    each of the ``n_sub`` substeps passes ``per_sub`` times over the springs and ``contact_passes`` times
    over those with both ends on the body, and sweeps the hanging ones once (or only the last substep);
    what a step's cost is made of (the passes are serial Gauss-Seidel, ~9 ns a visit). ``passed``: how
    many substeps' passes to leave out (1: only what ``finish_step`` itself visits, the first substep's
    passes being its caller's)."""
    a = finish_step_arguments(args)
    run = a["run"]
    n_sub = int(run.n_sub)
    sweeps = (n_sub if run.sweep_every_substep else 1) if run.sweep else 0
    per_step = {
        "springs": (n_sub - passed) * int(run.per_sub) * len(a["springs"].ends),
        "contact_springs": (n_sub - passed) * int(run.contact_passes) * len(a["on_body"].ends),
        "sweep_springs": sweeps * len(a["sweep"].ends),
    }
    return {"substeps": n_sub, "per_step": per_step, "total": sum(per_step.values())}


def perf(repeats: int = 3, settings: SimSettings = SimSettings()) -> dict:
    """Best-of-``repeats`` timings (wall, after a warm-up run) of a full drape; see the module doc."""
    with tempfile.TemporaryDirectory() as tmp:
        model = fine_garment(Path(tmp))
    body = build_body(Measurements(**PERF_BODY), Pose())
    drape(body, model, settings)  # compile and warm up
    best = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = drape(body, model, settings)
        wall = time.perf_counter() - t0
        if best is None or wall < best[0]:
            best = (wall, result)
    wall, result = best
    # the same drape phase by phase (start, the step loop, the relaxation, the full mesh and metrics), the
    # loop kernel by kernel: the kernels' times summed over its steps, and its own wall time per step
    # (kernels plus the Python and numpy between them)
    phases = {}
    t = time.perf_counter()
    d = start(body, model, settings)
    phases["start"] = time.perf_counter() - t
    with _Timer(capture_step=max(1, result.metrics["steps"] - 10)) as timer:
        t = time.perf_counter()
        while d.state.step < settings.max_steps and not step_drape(d):
            pass
        phases["loop"] = time.perf_counter() - t
    t = time.perf_counter()
    relaxation = relax(d)
    phases["relax"] = time.perf_counter() - t
    t = time.perf_counter()
    finish(d, relaxation)
    phases["finish"] = time.perf_counter() - t
    steps = d.state.step
    totals = timer.totals
    loop = sum(totals.values())
    loop_wall = phases["loop"] / max(1, steps)
    split = finish_step_split(timer.captured) if timer.captured else {}
    visits = spring_visits(timer.captured) if timer.captured else {}
    return {
        "garment_vertices": int(len(model.vertices)),
        "particles": int(len(model.coarse_index)),
        "springs": int(len(model.springs)),
        "body_vertices": int(len(body.vertices)),
        "settings": {"time_step": settings.time_step, "passes": settings.passes, "substeps": settings.substeps},
        "steps": result.metrics["steps"],
        "rest_reached": result.metrics["rest_reached"],
        "drape_wall_s": round(wall, 3),
        "polish_rounds": result.metrics["polish_rounds"],
        "phases_ms": {k: round(1000 * v, 1) for k, v in phases.items()},
        "ms_per_step": round(1000 * loop / steps, 3),
        "loop_wall_ms_per_step": round(1000 * loop_wall, 3),
        "ms_per_step_by_kernel": {k: round(1000 * v / steps, 3) for k, v in sorted(totals.items())},
        "finish_step_ms_near_rest": split,
        "spring_visits_near_rest": visits,
        # finish_step's time over the visits it makes
        "ns_per_spring_visit": round(1e6 * split["whole"] / spring_visits(timer.captured, passed=1)["total"], 2)
        if timer.captured else None,
        "penetrating_vertices": result.metrics["penetrating_vertices"],
        "max_strain": round(result.metrics["max_strain"], 3),
        "springs_over_target": sum(v["over"] for v in result.metrics["strain_by_kind"].values()),
    }


if __name__ == "__main__":
    print(json.dumps(perf(), indent=1))
