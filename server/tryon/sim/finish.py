"""The end of a drape: the shown (full) mesh rebuilt from the simulated one, and the drape's metrics."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from tryon.sim.collision.crossings import self_intersections
from tryon.sim.full_mesh import display_strain, follow_coarse
from tryon.sim.length import garment_ends
from tryon.sim.limbs import openings_on_shown_limbs
from tryon.sim.metrics import penetration_metrics, slid_metrics, strain_metrics, too_tight_places
from tryon.sim.relax import Relaxation
from tryon.sim.show_through import show_through_depth, show_through_metrics
from tryon.sim.state import Drape


@dataclass
class TryOnResult:
    """vertices (n, 3) full mesh, m; strain (n,) per full vertex; coarse (k, 3) simulated positions;
    metrics dict (steps, sim_seconds, wall_seconds, rest_reached, penetrating_vertices,
    max_penetration_mm, max_strain, strain_by_kind, too_tight (``metrics.too_tight_places``), ...)."""

    vertices: np.ndarray
    faces: np.ndarray
    strain: np.ndarray
    coarse: np.ndarray
    metrics: dict = field(default_factory=dict)


def finish(d: Drape, relaxation: Relaxation, stopped: bool = False) -> TryOnResult:
    """The full mesh of ``d``'s garment where it is now and the metrics of the drape. ``stopped``: the caller
    ended the step loop early (a client gone)."""
    full, full_parts = full_mesh(d)
    return result(d, relaxation, full, full_parts, stopped)


def full_mesh(d: Drape, also_collide: Callable[..., int] | None = None, alone: bool = True
              ) -> tuple[np.ndarray, np.ndarray]:
    """The shown mesh (n, 3) m of ``d``'s garment: it follows the coarse one, its stretch held to the limits,
    pushed out of the offset body (and out of whatever ``also_collide`` keeps it from, ``follow_coarse``);
    and the body parts (q,) int64 it can touch. ``alone``: the garment is not one of an outfit's (its settling
    rounds, ``follow_coarse``'s ``settle``)."""
    m = d.model
    return follow_coarse(m.garment, d.state.x, d.control.collider, m.limits, m.settings.contact_offset, m.floor_y,
                         also_collide, m.tuning.untangle_step, m.tuning.shown_untangle_rounds, settle=alone)


def result(d: Drape, relaxation: Relaxation, full: np.ndarray, full_parts: np.ndarray,
           stopped: bool = False) -> TryOnResult:
    """The result of ``d`` with the shown mesh ``full`` (n, 3) m (``full_mesh``, possibly moved since: an
    outfit's outer layers are pushed off the inner ones) and its metrics."""
    s, st, body, model, plan = d.model.settings, d.state, d.control.body, d.model.garment, d.control.plan
    x = st.x
    depth = d.control.collider.depth(full, full_parts, offset=False)
    spring_strain_, per_vertex, by_kind = strain_metrics(x, model, d.model.limits, on_body=st.has_plane.copy())
    too_tight = too_tight_places(x, model, spring_strain_, d.model.limits, st.has_plane, body, full)
    on_limbs = openings_on_shown_limbs(x, full, model, body, d.model.openings)
    metrics = {
        "steps": int(st.step),
        "sim_seconds": float(st.step * float(s.time_step)),
        "wall_seconds": float(time.perf_counter() - d.state.started),
        "rest_reached": bool(st.rest_reached),
        "balanced": bool(st.balanced),
        "rest_speed_mm_s": 1000.0 * st.speed if np.isfinite(st.speed) else None,
        "unbalanced_force": float(st.force) if np.isfinite(st.force) else None,
        "stopped": bool(stopped),
        **penetration_metrics(depth),
        **show_through_metrics(show_through_depth(d.control.collider, full_parts, full, model.faces)),
        "max_strain": float(spring_strain_.max()) if len(spring_strain_) else 0.0,
        "display_max_strain": display_strain(full, model),
        "self_crossings": self_intersections(full, model.faces, edges=model.edges),
        "strain_by_kind": by_kind,
        "too_tight": too_tight,
        "limb_openings": on_limbs,
        "openings_on_limbs": all(o["ok"] for o in on_limbs) if on_limbs else None,
        "ends_cm": garment_ends(full, model, body, d.model.openings, model.meta.category),
        **slid_metrics(d.model.placed_tops, full, d.model.piece[model.coarse_faces[model.attach_face, 0]]),
        "sized_to_body": d.model.sized,
        "kinetic_energy_per_kg": float(st.energy),
        "grown": bool(d.control.grow_steps),
        "arm_turn_deg": [float(np.degrees(plan.left)), float(np.degrees(plan.right))],
        "elbow_turn_deg": [float(np.degrees(plan.left_elbow)), float(np.degrees(plan.right_elbow))],
        "parts_tested": [body.parts[k] for k in d.control.parts],
        "last_step_contacts": int(st.collided),
        "polish_rounds": int(relaxation.rounds),
        "relax_move_mm": [float(1000 * relaxation.piece_move.max()), float(1000 * relaxation.relax_move.max())],
        "relaxed": bool(relaxation.relaxed),
        "pose": dict(body.pose),
    }
    if d.control.moving:  # a re-pose: the deepest any coarse point went inside the body on the way (``run.settle``)
        metrics["motion_max_penetration_mm"] = 1000.0 * d.state.motion_depth
    return TryOnResult(vertices=full, faces=model.faces, strain=per_vertex, coarse=x, metrics=metrics)
