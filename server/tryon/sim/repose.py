"""Re-posing a drape: the garment carried from one pose of a body to another, then stepped on from there.

``repose(d, body)`` takes a drape ``d`` (at rest or in motion) and the same person's body in a new pose (same
measurements and resolution: the same mesh topology, each part's vertices in the same order) and returns a new
``Drape`` on that body whose garment starts where the old one is:

1. each part's rigid motion between the poses (``part_motions``: the best rotation and translation between
   the part's vertices in one pose and the other, Kabsch; the limbs move rigidly, torso and head not at all);
2. the body moved from the old pose to the new over the first steps (``PoseTransition``, in the place of
   the arms' turn back from the sleeves, ``arms.ArmSchedule``: gravity off, every point tested), each limb
   turned about its joint a few degrees a step; a limb that never comes near the garment on its way (the
   arms over trousers) takes its new pose at once, and if none does the garment steps on at rest. A limb is
   not rigid from pose to pose (a hand turned at the wrist is part of its forearm; a raised upper arm is
   longer), so its shape goes from the old pose's to the new along with the turn (``BodyCollider.reshape``):
   the body starts exactly where the garment was draped on it, not with a hand 13 cm through its cuff;
3. every garment point carried by the parts near it each of those steps (``PoseTransition.weights``:
   linear blend skinning, each part weighted by the inverse fourth power of the point's distance to it
   where the part is that step (its nearest vertex, looked up in grids of the parts, ``nearest.py``), so a
   sleeve moves with its arm, the bodice stays with the torso, the armhole between them blends, and a shirt
   a hand leaves behind stops following the hand), as ``arms.py`` carries a sleeve: cloth near a moving limb
   moves with it, so it is neither left behind nor pushed through by it, and the collision and the springs
   settle the rest each step.

``start`` builds the new drape on the new body (the springs packed again, its collider, no alignment); then
``settle.settle`` steps it on as usual and ``relax`` and ``finish`` end it with the new pose's metrics.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from tryon.body.build import build_body, with_hands_straight
from tryon.body.params import Measurements, Pose
from tryon.body.types import Body
from tryon.garment.model import GarmentModel
from tryon.sim.collision.collider import BodyCollider
from tryon.sim.finish import TryOnResult
from tryon.sim.nearest import any_within, build_grids, nearest_distances
from tryon.sim.landmarks import arm_joints
from tryon.sim.settings import SimSettings
from tryon.sim.settle import settle
from tryon.sim.start import start
from tryon.sim.state import Drape
from tryon.sim.tuning import Tuning

# Exponent of the inverse-distance weights of the parts on a garment point: 4 makes a point within a few
# millimetres of one part and centimetres of the others follow that part almost alone (a sleeve on its arm),
# and blends points about as far from two parts (the armhole between the torso and the arm).
CARRY_POWER = 4.0
# Distance (m) added to every point-to-part distance before the weights: points on the body (distance ~0)
# would otherwise divide by zero, and within this distance of two parts a point blends them.
CARRY_SOFTEN = 0.005
# The body's motion from the old pose to the new is spread over steps: at most this many degrees of any
# part's turn, and this many metres of a hip joint's shift, per step (the arms' turn back from the sleeves
# goes at 1 degree per step, ``arms.ARM_DEG_PER_STEP``; here the cloth is carried along with the parts, so
# twice that keeps the body's surface within ~2 cm per step at the hand).
REPOSE_DEG_PER_STEP = 2.0
REPOSE_M_PER_STEP = 0.01
# A change smaller than this many steps' worth is not spread at all (the new body at once).
REPOSE_MIN_CHANGE = 0.5
# A part more than this many times farther from a garment point (distance + CARRY_SOFTEN) than the point's
# nearest part would weigh under CARRY_SPREAD ** -CARRY_POWER of it, and could be left out of the point's weights
# without looking its distance up (``nearest.nearest_distances``: the far parts cost most of a lookup). None is:
# at 10 (weights under 1e-4 left out, ~2 um of a hand's 2 cm step) the weights took ~2 ms a step instead of ~4,
# but the cloth's path through a re-pose changes with any last-bit change, and on that path the asymmetric pose
# of tests/test_ws_live.py had a point 10.5 mm inside the torso two steps after the motion (3.6 mm before, with
# k-d trees; 8.7 mm with every distance exact): every distance is looked up, as the trees did.
CARRY_SPREAD = np.inf
# m: a limb's shape differing from the old pose's by less than this everywhere is taken as rigid (its maps
# are not built again; a quarter of the collision margin, 4 mm).
SHAPE_TOLERANCE = 0.001
# m: the collider is given the changing shape whenever some vertex has moved this far since it was last given
# it (its maps take ~6 ms to build again): half the collision margin, so the cloth never meets a step in the
# surface deeper than its offset. The hand turning 90 degrees at the wrist moves 2.6 mm a step (every step),
# the raised arm's longer upper arm 0.5 mm a step (every 4th). At 4 mm the long-sleeve S, M and L re-posed
# to hands_on_hips ended with a cuff beside the hand 3 times in 3; at 2 mm, none.
RESHAPE_STEP = 0.002
# m: a limb whose surface comes no nearer the garment than this anywhere on its way from the old pose to the
# new is not moved over steps but at once: the garment cannot feel it (10 x the carry's softening, 10 x the
# contact planes' ``near``). Its way is looked at every ``MOTION_SAMPLE_DEG`` degrees of the largest turn
# (3 degrees: ~4 cm at the hand of a 75 cm arm, under the reach, so no pass by the garment goes unseen).
CARRY_REACH = 0.05
MOTION_SAMPLE_DEG = 3.0


# Of the elbow-to-wrist length: a forearm's vertices nearer its elbow than this are the forearm's own, whose
# rigid motion it makes between two poses whose hands are turned differently (the wrist's own ring turns half
# as far as the hand). A hand turned 80-90 degrees then leaves the forearm turned under a degree (the sections'
# spline bends a little towards the wrist; 0.4-0.9 degrees for 0.5-0.9 of the length), where the whole part's
# fit turned it 23-25 degrees.
FOREARM_OWN = 0.9


def _without_a_turned_hand(old: Body, new: Body, k: int, ids: np.ndarray) -> np.ndarray:
    """The vertices ``ids`` of part k to fit its rigid motion from ``old`` to ``new`` on: all of them, except for a
    forearm whose hand is turned otherwise in the two poses, the forearm's own (``FOREARM_OWN``). Fitted on the
    hand too, the forearm's motion was skewed towards the hand's turn, the turn was left to the shape change,
    and half-way through it the forearm stood off its cylinder map's axis (cloth 2 cm outside it judged 2 cm
    inside)."""
    name = old.parts[k]
    if not name.startswith("forearm_"):
        return ids
    side = "left" if name.endswith("_l") else "right"
    if old.pose.get(f"wrist_bend_{side}", 0.0) == new.pose.get(f"wrist_bend_{side}", 0.0):
        return ids
    elbow, wrist = np.asarray(old.joints[f"elbow_{name[-1]}"]), np.asarray(old.joints[f"wrist_{name[-1]}"])
    own = np.linalg.norm(old.vertices[ids] - elbow, axis=1) < FOREARM_OWN * np.linalg.norm(wrist - elbow)
    return ids[own]


def part_motions(old: Body, new: Body) -> np.ndarray:
    """(P, 4, 4) rigid motion of every part from ``old`` to ``new`` (same topology): the rotation and
    translation that best map the part's old vertices onto its new ones (Kabsch, least squares)."""
    if old.faces.shape != new.faces.shape or len(old.vertices) != len(new.vertices):
        raise ValueError("re-posing needs the same body in another pose (same measurements and resolution)")
    out = np.tile(np.eye(4), (len(old.parts), 1, 1))
    vertex_part = old.vertex_part
    for k in range(len(old.parts)):
        ids = np.flatnonzero(vertex_part == k)
        ids = _without_a_turned_hand(old, new, k, ids)
        a, b = old.vertices[ids], new.vertices[ids]
        ca, cb = a.mean(axis=0), b.mean(axis=0)
        u, _, vt = np.linalg.svd((a - ca).T @ (b - cb))
        d = np.sign(np.linalg.det(vt.T @ u.T))
        rot = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
        out[k, :3, :3] = rot
        out[k, :3, 3] = cb - rot @ ca
    return out


class PoseTransition:
    """The body moved from an old pose to its own (new) pose over ``steps`` steps, carrying the garment:
    the drape's ``arms`` in place of an ``arms.ArmSchedule`` (the same three calls: ``apply``, ``attach``,
    ``carry``, and ``steps`` / ``turned_parts``), so ``step`` runs it as the start-up's arm turn.

    Each limb is turned about its proximal joint (shoulder, elbow, hip, knee) by the fraction of its
    rotation from the new pose back to the old one still left, the joint carried by the limb above it (so
    forearm and upper arm stay joined all the way); torso and head do not move. Garment points move with
    the parts near them (``weights``)."""

    def __init__(self, old: Body, new: Body, collider: BodyCollider | None = None, garment: np.ndarray | None = None):
        """The motion from ``old`` to ``new`` (the limbs that move near the ``garment`` (k, 3) m, how many steps,
        the limbs' change of shape): all of it known before the drape's collider is (``bind``), so a live
        session can tell the client the new body's first frame while the drape is set up."""
        self.new, self.collider = new, collider
        # where the motion starts: the old body and the garment on it (``through_midway`` carries it again)
        self.old, self.garment = old, None if garment is None else np.array(garment, dtype=np.float64)
        back = part_motions(new, old)  # (P, 4, 4): new pose -> old pose, per part
        self.back_rot = Rotation.from_matrix(back[:, :3, :3]).as_rotvec()  # (P, 3) radians
        # each part's turn as Rodrigues' terms: R(f) = I + sin(f angle) K + (1 - cos(f angle)) K^2, K the cross
        # product with the unit axis (``geometry.rotation``'s terms, so the same matrices to the bit)
        # (P,) radians, each norm on its own: np.linalg.norm(..., axis=1) rounds differently in the last bit, and
        # the cloth's path through a re-pose is that sensitive (step counts 88 -> 92 for hands_on_hips)
        self._angle = np.array([np.linalg.norm(r) for r in self.back_rot])
        self._k1 = np.zeros((len(new.parts), 3, 3))
        self._k2 = np.zeros((len(new.parts), 3, 3))
        for k in np.flatnonzero(self._angle > 0.0):
            a = self.back_rot[k] / np.linalg.norm(self.back_rot[k])
            self._k1[k] = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
            self._k2[k] = self._k1[k] @ self._k1[k]
        self.chains = []  # (part, parent part | None, joint of the new body (3,))
        for side in ("l", "r"):
            for part, parent, joint in ((f"upper_arm_{side}", None, f"shoulder_{side}"),
                                        (f"forearm_{side}", f"upper_arm_{side}", f"elbow_{side}"),
                                        (f"thigh_{side}", None, f"hip_{side}"),
                                        (f"shin_{side}", f"thigh_{side}", f"knee_{side}")):
                if part in new.parts and joint in new.joints:
                    k = new.parts.index(part)
                    up = new.parts.index(parent) if parent is not None else None
                    self.chains.append((k, up, np.asarray(new.joints[joint], dtype=np.float64),
                                        np.asarray(old.joints[joint], dtype=np.float64)))
        # each part's vertices in the collider's rest shape (the new body's pose), binned in grids
        # (``nearest``): a garment point is weighed against the parts where they are now, by taking it into each
        # part's rest frame
        self._vertex_part = np.ascontiguousarray(new.vertex_part, dtype=np.int64)
        self._grids = build_grids(new.vertices, self._vertex_part, len(new.parts))
        if garment is not None:
            self.chains = self._near(self.chains, garment)
        kept = [k for k, _, _, _ in self.chains]
        angles = np.linalg.norm(self.back_rot[kept], axis=1) if kept else np.zeros(0)
        shifts = [np.linalg.norm(j_old - j_new) for _, up, j_new, j_old in self.chains if up is None]
        self.reshaping = self._shape_change(old, kept)  # (n, 3) m
        self._reshape_max = float(np.linalg.norm(self.reshaping, axis=1).max(initial=0.0))
        self._reshaped_parts = np.unique(self._vertex_part[self.reshaping.any(axis=1)])
        biggest = max(np.degrees(angles.max(initial=0.0)) / REPOSE_DEG_PER_STEP,
                      max(shifts, default=0.0) / REPOSE_M_PER_STEP,
                      self._reshape_max / REPOSE_M_PER_STEP)
        self.steps = int(np.ceil(biggest)) if biggest > REPOSE_MIN_CHANGE else 0
        self._last: np.ndarray | None = None
        self._shaped = 0.0  # the fraction of the old shape the collider was last given (``apply``)
        self._moves = np.tile(np.eye(4), (len(new.parts), 1, 1))
        self._attached = False

    def _near(self, chains: list, garment: np.ndarray) -> list:
        """The limbs of ``chains`` that move and come within ``CARRY_REACH`` of a garment point (``garment``
        (k, 3) m) at some moment of their motion (every ``MOTION_SAMPLE_DEG`` degrees, both ends included): the
        others take the new pose at once (trousers do not wait for the arms to rise, gravity off, nor settle
        again after it). A limb is its upper part and the part hanging from it, kept or left together. The
        garment is looked up in each part's grid (``nearest.any_within``), taken into the part's rest frame."""
        garment = np.ascontiguousarray(garment, dtype=np.float64)
        near = set()
        self.chains = chains
        turn = np.degrees(np.linalg.norm(self.back_rot[[k for k, _, _, _ in chains]], axis=1).max(initial=0.0))
        for fraction in np.linspace(0.0, 1.0, max(2, int(np.ceil(turn / MOTION_SAMPLE_DEG)) + 1)):
            moves = self._motions(fraction)
            for k, _, _, _ in chains:
                if k not in near and any_within(garment, moves[k], k, *self._grids, CARRY_REACH):
                    near.add(k)
        root = {}
        for k, up, j_new, j_old in chains:
            root[k] = root.get(up, up) if up is not None else k
            if np.linalg.norm(self.back_rot[k]) < 1e-9 and np.linalg.norm(j_old - j_new) < 1e-9:
                near.discard(k)  # it does not move: nothing to carry
        keep_roots = {root[k] for k in near}
        return [c for c in chains if root[c[0]] in keep_roots]

    def _shape_change(self, old: Body, kept: list[int]) -> np.ndarray:
        """(n, 3) m: how far each body vertex of the moving parts ``kept`` is from the old body's, in the new
        pose's frame, when the part is moved back to the old pose (``_motions(1.0)``): a limb is not rigid
        from one pose to another (the hand turned at the wrist is part of the forearm, up to 13.5 cm off
        from hands_on_hips to the A-pose; the upper arm is longer raised, its elbow 4 cm off). The body's
        shape goes from the old to the new along with the motion (``apply``), so it starts where the garment
        was draped and not a hand's turn away from it. Zero where the shapes agree (within
        ``SHAPE_TOLERANCE``)."""
        vp = self._vertex_part
        back = np.linalg.inv(self._motions(1.0))[vp]  # (n, 4, 4): old pose -> new pose, per vertex's part
        change = np.einsum("nij,nj->ni", back[:, :3, :3], old.vertices) + back[:, :3, 3] - self.new.vertices
        change[~np.isin(vp, kept)] = 0.0
        if np.linalg.norm(change, axis=1).max(initial=0.0) < SHAPE_TOLERANCE:
            change[:] = 0.0
        return change

    def bind(self, collider: BodyCollider) -> "PoseTransition":
        """Move the drape's ``collider`` (its body is ``new``) from now on; this transition, for ``start``'s
        ``motion``."""
        self.collider = collider
        return self

    def start_motion(self) -> np.ndarray | None:
        """(P, 4, 4) the motion of every part from the new pose at step 0 (the body still in the old pose, as
        ``apply(0)`` leaves it), or None when there is no motion over steps (the body takes its new pose at
        once)."""
        return self._motions(1.0) if self.steps else None

    def turned_parts(self) -> list[int]:
        return [k for k, _, _, _ in self.chains]

    def _motions(self, fraction: float) -> np.ndarray:
        """(P, 4, 4) motion of every part from the new pose with ``fraction`` of the way back left."""
        out = np.tile(np.eye(4), (len(self.new.parts), 1, 1))
        for k, up, j_new, j_old in self.chains:  # parents come before their children
            angle = fraction * float(self._angle[k])
            rot = np.eye(3) + np.sin(angle) * self._k1[k] + (1 - np.cos(angle)) * self._k2[k] if angle > 0.0 \
                else np.eye(3)
            joint = (out[up, :3, :3] @ j_new + out[up, :3, 3]) if up is not None else j_new + fraction * (j_old - j_new)
            out[k, :3, :3] = rot
            out[k, :3, 3] = joint - rot @ j_new
        return out

    def apply(self, step: int) -> None:
        """Pose the body for ``step`` (0: the old pose; ``steps`` and after: its own)."""
        fraction = 1.0 - min(1.0, step / self.steps) if self.steps else 0.0
        moves = self._motions(fraction)
        # the shape is given in steps of RESHAPE_STEP, its ends exactly
        if self.reshaping.any() and fraction != self._shaped and (
                fraction in (0.0, 1.0) or abs(fraction - self._shaped) * self._reshape_max >= RESHAPE_STEP):
            shape = self.new.vertices + fraction * self.reshaping
            self.collider.reshape(shape if fraction > 0.0 else None, self._reshaped_parts)
            self._grids = build_grids(shape, self._vertex_part, len(self.new.parts))
            self._shaped = fraction
        self.collider.pose_arms({k: (np.zeros(3), moves[k, :3, :3], moves[k, :3, 3]) for k in self.turned_parts()})
        self._last, self._moves = self._moves, moves

    def current(self) -> np.ndarray:
        """(P, 4, 4) the motion of every part from the new pose as last applied (the body's shape now)."""
        return self._moves

    def attach(self, x: np.ndarray, faces: np.ndarray) -> None:
        """Start carrying the garment (``faces`` unused: the weights are by distance, not over the cloth);
        call after ``apply(0)``."""
        self._attached = True

    def weights(self, x: np.ndarray, moves: np.ndarray, moving: np.ndarray) -> np.ndarray:
        """(k, m) weights of the ``moving`` (m,) parts on the garment points x (k, 3) m, the body posed by
        ``moves`` (P, 4, 4): ``(distance to the part + CARRY_SOFTEN) ** -CARRY_POWER`` over the sum of every
        part's (distance to the part's nearest vertex, m: ``nearest.nearest_distances``; see ``CARRY_SPREAD``).
        Taken again every step, so cloth a hand leaves behind (a shirt under a hand lifted off the hip) stops
        following it; taken once, the shirt was dragged along and came out of the next pose with a sleeve off
        the arm. Every step, not every few: taken every 2 or 4 steps the shirt came off an arm somewhere in 18
        re-poses in a row where it did not so. With a k-d tree per part they cost ~6-9 ms a step for the
        T-shirt's 874 points, with the grids ~3-4 ms."""
        dist = np.empty((len(x), len(self.new.parts)))
        wanted = np.zeros(len(self.new.parts), dtype=np.bool_)
        wanted[moving] = True
        nearest_distances(np.ascontiguousarray(x, dtype=np.float64), np.ascontiguousarray(moves), wanted,
                          *self._grids, CARRY_SOFTEN, CARRY_SPREAD, dist)
        w = (dist + CARRY_SOFTEN) ** -CARRY_POWER  # 0 for the parts left out (inf)
        return w[:, moving] / w.sum(axis=1, keepdims=True)

    def carry(self, x: np.ndarray, x_prev: np.ndarray) -> None:
        """Move the garment points (x and x_prev (k, 3), in place) by the parts' motions between the last two
        ``apply`` calls, blended by their weights on the body as it was before this motion."""
        if not self._attached or self._last is None:
            return
        step = self._moves @ np.linalg.inv(self._last)  # (P, 4, 4)
        moving = np.flatnonzero(np.abs(step - np.eye(4)).max(axis=(1, 2)) > 1e-12)
        if not len(moving):
            return
        w = self.weights(x, self._last, moving)  # (k, m)
        for p in (x, x_prev):
            moved = np.einsum("mij,kj->kmi", step[moving, :3, :3], p) + step[moving, :3, 3][None]  # (k, m, 3)
            p += np.einsum("km,kmi->ki", w, moved - p[:, None, :])


def repose(d: Drape, body: Body, transition: PoseTransition | None = None) -> Drape:
    """A drape on ``body`` (``d``'s body in a new pose) whose garment starts where ``d``'s is and is carried
    along as the body moves from the old pose to the new over the first steps (``transition``, made here if
    not given: ``PoseTransition(d.control.body, body, garment=d.state.x)``); see the module doc. ``d`` is left as it
    was."""
    m = d.model
    return carry(d.control.body, d.state.x, m.garment, m.settings, m.tuning, body, transition, m.sized,
                 d.state.folded)


def carry(old: Body, garment: np.ndarray, model: GarmentModel, settings: SimSettings, tuning: Tuning, body: Body,
          transition: PoseTransition | None = None, sized: bool = False, folded: np.ndarray | None = None) -> Drape:
    """``repose`` from the ``garment`` (k, 3) m of ``model`` as it lies on ``old`` (no drape needed: a re-pose
    done again from where it started, ``through_midway``). ``sized``: ``model`` is a garment of guessed units
    sized to this person (``start``), as the drape it comes from says: it stays so in every pose. ``folded``: the
    springs still folded where it lies (``DrapeState.folded``; trouser legs bunched on the feet stay so)."""
    if transition is None:
        transition = PoseTransition(old, body, garment=garment)
    return start(body, model, settings, tuning, initial=garment.copy(), motion=transition.bind, sized=sized,
                 folded=folded)


def redrape_if_off(d: Drape, result: TryOnResult, on_frame=None) -> tuple[Drape, TryOnResult, bool]:
    """A re-posed drape that came to rest with a sleeve or a trouser leg off its limb (``openings_on_limbs``
    False) draped afresh in the same pose (aligned, as a new try-on) when that puts them on, else carried again
    from where the re-pose started through the midway pose (``through_midway``) when that does: (the drape, its
    result, whether it was draped again). Carried through many poses in a row the cloth can end caught on the
    way (the T-shirt M, six poses three times over: a sleeve came off at the tenth and stayed off), and a later
    pose would start from there. A garment sized to the body (guessed units) is left as it is. The result draped
    again keeps the re-pose's ``motion_max_penetration_mm`` (or the deeper of the carries')."""
    if result is None or result.metrics.get("openings_on_limbs") is not False or d.model.sized:
        return d, result, False
    fresh, again = fresh_drape(d.control.body, d.model.garment, d.model.settings, d.model.tuning, on_frame)
    if again.metrics.get("openings_on_limbs") is not False:
        # the motion the client saw was the re-pose's (the fresh drape's start grows the body inside the cloth)
        again.metrics["motion_max_penetration_mm"] = result.metrics.get("motion_max_penetration_mm")
        return fresh, again, True
    carried = through_midway(d, on_frame)
    if carried is None or carried[1].metrics.get("openings_on_limbs") is False:
        return d, result, False
    deeper = max(result.metrics.get("motion_max_penetration_mm") or 0.0,
                 carried[1].metrics.get("motion_max_penetration_mm") or 0.0)
    carried[1].metrics["motion_max_penetration_mm"] = deeper
    return carried[0], carried[1], True


def through_midway(d: Drape, on_frame=None) -> tuple[Drape, TryOnResult] | None:
    """The re-pose ``d`` done again in two halves: from where it started (its transition's old body and the
    garment on it) to the midway pose (every angle halfway; not streamed), then on to ``d``'s pose (streamed to
    ``on_frame``): (the drape, its result, counting both halves' steps and time), or None when ``d`` is not a
    re-pose of a body ``build_body`` made. A big move in one go (an arm swung 80 degrees forward while its elbow
    bends 110) can leave a sleeve caught beside the arm where a fresh drape in that pose leaves it off too: the
    three such settles of the motion stress's twenty sequences (the long-sleeves M and XXL) end on the arms so."""
    t = d.control.arms
    if not isinstance(t, PoseTransition) or t.garment is None or t.old.resolution is None or not t.old.pose:
        return None
    old, new = t.old.pose, d.control.body.pose
    mid = {k: 0.5 * (old[k] + v) if isinstance(v, float) and isinstance(old.get(k), float) else v
           for k, v in new.items()}
    m, body = d.model, d.control.body
    half = carry(t.old, t.garment, m.garment, m.settings, m.tuning,
                 build_body(Measurements(**body.requested), Pose(**mid), body.resolution), sized=m.sized,
                 folded=d.state.folded)
    first, _ = settle(half)
    again, result = settle_after(half, first, body, on_frame)
    result.metrics["motion_max_penetration_mm"] = max(first.metrics.get("motion_max_penetration_mm") or 0.0,
                                                      result.metrics.get("motion_max_penetration_mm") or 0.0)
    return again, result


def settle_after(first_drape: Drape, first: TryOnResult, body: Body, on_frame=None) -> tuple[Drape, TryOnResult]:
    """``first_drape``, settled (its result ``first``), re-posed to ``body`` and settled: (the drape, its result).
    The frames' steps run on from the first settle's; the metrics count the steps and the time of both."""
    steps = first.metrics["steps"]
    d = repose(first_drape, body)
    result, _ = settle(d, None if on_frame is None else lambda step, x: on_frame(steps + step, x))
    for key in ("steps", "sim_seconds", "wall_seconds"):
        result.metrics[key] += first.metrics[key]
    return d, result


def fresh_drape(body: Body, model: GarmentModel, settings: SimSettings, tuning: Tuning, on_frame=None
                ) -> tuple[Drape, TryOnResult]:
    """``model`` draped afresh on ``body`` (aligned, stepped to rest): (the drape, its result). A long sleeve on a
    body whose hands are turned at the wrist (``Body.hands_turned``) is draped on the body with its hands
    straight, then re-posed to the turned hands (``repose``: the hand's turn carries the cuff round it): draped
    with the hands turned from the start, the hand stood out through the sleeve's side and the cuff ended
    crumpled beside the forearm (the catalogue's long sleeves S, M, L with both wrists turned +-60 or +-85
    degrees, in hands_on_hips or with the elbows at 90 and the wrists at 70: 15 cuffs of 36 round the arms; 36
    so). It costs a second settle (of the hand's turn), so only where a sleeve reaches past an elbow
    (``long_sleeves``). The frames' steps run on from the first settle's; the metrics count the steps and the
    time of both, and ``motion_max_penetration_mm`` is the hand's turn's."""
    d = start(body, model, settings, tuning)
    straight = with_hands_straight(body) if body.hands_turned and long_sleeves(d) else body
    if straight is body:
        return d, settle(d, on_frame)[0]
    straight = start(straight, model, settings, tuning)
    first, _ = settle(straight, on_frame)
    return settle_after(straight, first, body, on_frame)


def long_sleeves(d: Drape) -> bool:
    """Whether a sleeve of ``d``'s garment (the far opening the arm plan found) lies farther from its shoulder
    joint than the elbow is, where the drape starts (round the forearm or the hand, not the upper arm)."""
    for side, cuff in (("l", d.control.plan.left_cuff), ("r", d.control.plan.right_cuff)):
        if cuff is not None and f"forearm_{side}" in d.control.body.parts:
            joint, elbow, _ = arm_joints(d.control.body, side)
            if np.linalg.norm(d.state.x[cuff].mean(axis=0) - joint) > np.linalg.norm(elbow - joint):
                return True
    return False
