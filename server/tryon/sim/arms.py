"""The arms' start-up turn back from the sleeve pose (``align.plan_arms``) to the body's own pose, carrying
the sleeves with them.

``ArmSchedule`` turns each posed arm back over the first steps (``ARM_DEG_PER_STEP``): the upper arm about
the shoulder joint, the forearm with it and then about the turned elbow. Collision alone drags a sleeve
along only where the arm presses on it: a cuff round a hand is pushed on one side while the rest of the
sleeve keeps its angle, so the ring is pulled flat across the hand and the hand slips out through its side
(the catalogue's long-sleeve M on the medium body at arm angles 10-70 degrees, made for 30: one cuff beside
the hand). So each step also moves the sleeve's points by the arm's own motion that step (linear blend
skinning): a point's weight on the arm grows from 0 at the armhole to 1 down the sleeve, and its weight
on the forearm from 0 above the elbow to 1 below it. Where a point lies along the sleeve is measured over
the cloth, as the distance from the cuff (``sleeve_weights``), not in space: the bodice beside a hanging
arm is near the arm but far from the cuff round the seams, and is not carried.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from tryon.body.types import Body
from tryon.garment.topology import cloth_distance
from tryon.sim.arm_plan import ArmPlan
from tryon.sim.landmarks import arm_joints
from tryon.geometry import rotation
from tryon.sim.collision.collider import BodyCollider

# Degrees per 0.02 s step (``settings.REFERENCE_STEP``; ``step_fraction`` scales it to the time step) the arms
# are turned back from the sleeve pose (slow enough that the arm surface moves ~1 cm per step at the wrist,
# well under an arm's radius: no tunnelling through the sleeve).
ARM_DEG_PER_STEP = 1.0
# Along the sleeve from the shoulder joint, as fractions of the upper arm's length: a point's weight on
# the arm ramps from 0 to 1 between these (the sleeve cap and armhole stay with the bodice).
CARRY_RAMP = (0.1, 0.4)
# Either side of the elbow, as a fraction of the upper arm's length: the ramp of the forearm's weight.
ELBOW_RAMP = 0.15


def _affine(pivot: np.ndarray, rot: np.ndarray, shift: np.ndarray | None = None) -> np.ndarray:
    """(4, 4) matrix of v -> pivot + rot (v - pivot) + shift."""
    a = np.eye(4)
    a[:3, :3] = rot
    a[:3, 3] = pivot - rot @ pivot + (0.0 if shift is None else shift)
    return a


def _ramp(t: np.ndarray, lo: float, hi: float) -> np.ndarray:
    return np.clip((t - lo) / (hi - lo), 0.0, 1.0)


def sleeve_weights(x: np.ndarray, faces: np.ndarray, cuff: np.ndarray, joint: np.ndarray, elbow: np.ndarray,
                   wrist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Skinning weights (k,) each, in [0, 1], of the garment points x (k, 3) (faces (f, 3)) on an arm posed
    along its sleeve, whose joints are ``joint``, ``elbow``, ``wrist`` (3,) m and whose sleeve ends at the
    opening ``cuff`` (q,) int: (on the arm, on the forearm rather than the upper arm).

    A point's place along the arm is the cuff's place (its centre's projection onto the arm, as a length
    from the shoulder joint) less the point's distance from the cuff over the cloth (``cloth_distance``):
    down a sleeve the two agree, and a point of the bodice, reached from the cuff only round the armhole,
    comes out near the shoulder or before it (weight 0)."""
    upper = float(np.linalg.norm(elbow - joint))
    fore = float(np.linalg.norm(wrist - elbow))
    c = x[cuff].mean(axis=0)
    along_fore = float(np.clip((c - elbow) @ (wrist - elbow) / fore, 0.0, None)) if fore > 0.0 else 0.0
    if along_fore > 0.0:
        cuff_at = upper + along_fore
    else:
        cuff_at = float(np.clip((c - joint) @ (elbow - joint) / upper, 0.0, upper))
    at = cuff_at - cloth_distance(x, faces, cuff)
    on_arm = _ramp(at, CARRY_RAMP[0] * upper, CARRY_RAMP[1] * upper)
    on_fore = _ramp(at, upper * (1.0 - ELBOW_RAMP), upper * (1.0 + ELBOW_RAMP))
    return on_arm, on_fore


class _Arm(NamedTuple):
    """One arm the schedule turns: its joints (3,) m at rest, the plan's shoulder turn (radians, unit axis
    (3,)) and elbow turn (radians, axis (3,) in the rest pose), and its part indices (no forearm: None)."""

    joint: np.ndarray
    elbow: np.ndarray
    wrist: np.ndarray
    angle: float
    axis: np.ndarray
    bend: float
    bend_axis: np.ndarray
    k_up: int
    k_fore: int | None


class ArmSchedule:
    """Turns the arms from the sleeve pose (``plan``) back to the body's pose over ``steps`` steps, every
    angle scaled by the fraction of the pose left; ``carry`` moves the sleeves along (module doc).
    ``step_fraction``: the time step over ``settings.REFERENCE_STEP`` (a finer step turns them less a step)."""

    def __init__(self, body: Body, collider: BodyCollider, plan: ArmPlan, step_fraction: float = 1.0):
        self.collider = collider
        self.plan = plan
        self.parts = {}
        for side, angle, axis, bend, bend_axis in (
                ("l", plan.left, plan.left_axis, plan.left_elbow, plan.left_elbow_axis),
                ("r", plan.right, plan.right_axis, plan.right_elbow, plan.right_elbow_axis)):
            if (angle == 0.0 and bend == 0.0) or f"upper_arm_{side}" not in body.parts:
                continue
            k_up = body.parts.index(f"upper_arm_{side}")
            k_fore = body.parts.index(f"forearm_{side}") if f"forearm_{side}" in body.parts else None
            joint, elbow, wrist = arm_joints(body, side) if k_fore is not None else (
                body.part_axes[k_up, 0].copy(), body.part_axes[k_up, 1].copy(), body.part_axes[k_up, 1].copy())
            self.parts[side] = _Arm(joint, elbow, wrist, angle, np.asarray(axis, dtype=np.float64), bend,
                                    np.asarray(bend_axis, dtype=np.float64), k_up, k_fore)
        biggest = max((max(abs(a.angle), abs(a.bend)) for a in self.parts.values()), default=0.0)
        self.steps = int(np.ceil(np.degrees(biggest) / (ARM_DEG_PER_STEP * step_fraction))) if self.parts else 0
        self._last = {}
        self._moves = {}  # side -> (upper arm, forearm) (4, 4) motions of the last ``apply``
        self._weights = {}  # side -> (on arm, on forearm) weights of the garment points

    def turned_parts(self) -> list[int]:
        """Body part indices the schedule moves."""
        return [k for a in self.parts.values() for k in (a.k_up, a.k_fore) if k is not None]

    def _motions(self, fraction: float) -> dict[str, tuple[tuple, tuple | None]]:
        """Per side, the (pivot, R[, shift]) motion of the upper arm and of the forearm (None: no forearm)
        with ``fraction`` of the sleeve pose left."""
        out = {}
        for side, a in self.parts.items():
            rot = rotation(a.axis, a.angle * fraction)
            up = (a.joint, rot)
            if a.k_fore is None:
                out[side] = (up, None)
            elif a.bend == 0.0:
                out[side] = (up, up)
            else:
                # forearm: v -> e' + R_e (R_s (v - j) + j - e'), e' the turned elbow, R_e about the turned axis
                posed_elbow = a.joint + rot @ (a.elbow - a.joint)
                rot_e = rotation(rot @ a.bend_axis, a.bend * fraction)
                out[side] = (up, (a.joint, rot_e @ rot, (np.eye(3) - rot_e) @ (posed_elbow - a.joint)))
        return out

    def apply(self, step: int) -> None:
        """Pose the arms for ``step`` (0: the sleeve pose; ``steps`` and after: the body's own pose)."""
        fraction = 1.0 - min(1.0, step / self.steps) if self.steps else 0.0
        turns = {}
        moves = {}
        for side, (up, fore) in self._motions(fraction).items():
            turns[self.parts[side].k_up] = up
            if fore is not None:
                turns[self.parts[side].k_fore] = fore
            moves[side] = (_affine(*up), _affine(*fore) if fore is not None else _affine(*up))
        self.collider.pose_arms(turns)
        self._last, self._moves = self._moves, moves

    def attach(self, x: np.ndarray, faces: np.ndarray) -> None:
        """Weigh the garment points x (k, 3) (faces (f, 3)) on each posed arm whose sleeve has a known cuff
        (``sleeve_weights``); call after ``apply(0)``."""
        for side, a in self.parts.items():
            cuff = self.plan.left_cuff if side == "l" else self.plan.right_cuff
            if cuff is None:
                continue
            up, fore = self._moves[side]
            posed = [(m @ np.append(p, 1.0))[:3] for m, p in ((up, a.joint), (up, a.elbow), (fore, a.wrist))]
            self._weights[side] = sleeve_weights(x, faces, cuff, *posed)

    def carry(self, x: np.ndarray, x_prev: np.ndarray) -> None:
        """Move the sleeve points (positions x and previous positions x_prev (k, 3), in place) by their
        arm's motion between the last two ``apply`` calls, blended by their weights."""
        for side, (on_arm, on_fore) in self._weights.items():
            if side not in self._last:
                continue
            (up0, fore0), (up1, fore1) = self._last[side], self._moves[side]
            step_up, step_fore = up1 @ np.linalg.inv(up0), fore1 @ np.linalg.inv(fore0)
            moved = on_arm > 0.0
            w_arm, w_fore = on_arm[moved, None], on_fore[moved, None]
            for p in (x, x_prev):
                by_up = p[moved] @ step_up[:3, :3].T + step_up[:3, 3]
                by_fore = p[moved] @ step_fore[:3, :3].T + step_fore[:3, 3]
                p[moved] += w_arm * ((1.0 - w_fore) * by_up + w_fore * by_fore - p[moved])
