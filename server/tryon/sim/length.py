"""Where a drape's ends lie on the body, measured on the shown mesh: each long sleeve's cuff against the wrist,
each full-length trouser leg's hem against the ankle, a top's or dress's hem against the hips line (issue 52's
length: the size advice says too long or too short from these, ``fit.verdict``).

A sleeve is long when its cuff lies on the forearm or past it (its centre farther from the shoulder joint than
the elbow); a leg is full length when its hem lies below the knee. The ankle is not a joint of the body model:
its height is 3.9 % of the body's (the lateral malleolus, Drillis and Contini's segment proportions).
"""

from __future__ import annotations

import numpy as np

from tryon.body.types import Body
from tryon.sim.landmarks import body_landmarks
from tryon.sim.limbs import shown_openings

# Of the body's height: the ankle bone above the floor (Drillis and Contini 1966, 0.039 H).
ANKLE_HEIGHT = 0.039


def ankle_y(body: Body) -> float:
    """m: the height of the body's ankle bones (``ANKLE_HEIGHT`` of its built height)."""
    return ANKLE_HEIGHT * body.achieved["height"] / 100.0


def forearm(body: Body, s: str) -> tuple[np.ndarray, np.ndarray]:
    """The wrist joint (3,) m of side ``s`` ('l' or 'r') and the forearm's unit direction (3,), elbow to wrist."""
    elbow, wrist = np.asarray(body.joints[f"elbow_{s}"]), np.asarray(body.joints[f"wrist_{s}"])
    return wrist, (wrist - elbow) / np.linalg.norm(wrist - elbow)


def _centre(full: np.ndarray, ring: np.ndarray) -> np.ndarray:
    return full[ring].mean(axis=0)


def _cuff_past_wrist(centre: np.ndarray, body: Body, s: str) -> float | None:
    """cm the cuff's centre lies past the wrist joint along the forearm (negative: short of it), or None for a
    short sleeve (its cuff nearer the shoulder than the elbow)."""
    shoulder, elbow = np.asarray(body.joints[f"shoulder_{s}"]), np.asarray(body.joints[f"elbow_{s}"])
    if np.linalg.norm(centre - shoulder) < np.linalg.norm(elbow - shoulder):
        return None
    wrist, axis = forearm(body, s)
    return 100.0 * float((centre - wrist) @ axis)


def _hem_over_ankle(centre: np.ndarray, body: Body, s: str) -> float | None:
    """cm the leg hem's centre lies above the ankle bone (negative: below it, towards the floor), or None for a
    leg ending above the knee."""
    if centre[1] > np.asarray(body.joints[f"knee_{s}"])[1]:
        return None
    return 100.0 * float(centre[1] - ankle_y(body))


def garment_ends(full: np.ndarray, model, body: Body, openings: list[tuple[str, str, np.ndarray]],
                 category: str) -> dict[str, float]:
    """Where the shown mesh ``full`` (n, 3) m of ``model`` ends on ``body``, cm: ``sleeve_l`` / ``sleeve_r`` past
    the wrist (long sleeves), ``leg_l`` / ``leg_r`` above the ankle bone (full-length legs), ``hem`` below the
    hips line (tops: the lowest opening that is no limb's; a dress's length is its style's). ``openings``: the drape's limb openings
    (``limbs.limb_openings``, on the coarse mesh). Empty for a body without joints (not built by
    ``build_body``)."""
    if not body.joints or "height" not in body.achieved or not len(full):
        return {}
    out: dict[str, float] = {}
    rings = shown_openings(model, openings)
    for side, limb, ring in rings:
        s = side[0]
        centre = _centre(full, ring)
        key = f"sleeve_{s}" if limb == "arm" else f"leg_{s}"
        value = _cuff_past_wrist(centre, body, s) if limb == "arm" else _hem_over_ankle(centre, body, s)
        if value is None:
            continue
        # of a sleeve's openings (armhole and cuff), the cuff is the one farthest out
        if key not in out or (value > out[key] if limb == "arm" else value < out[key]):
            out[key] = round(value, 1)
    if category == "top":
        limb_vertices = set(int(v) for _, _, ring in rings for v in ring)
        hems = [loop for loop in model.loops if not limb_vertices.intersection(int(v) for v in loop)]
        if hems:
            lowest = min(hems, key=lambda loop: float(full[loop, 1].mean()))
            out["hem"] = round(100.0 * (body_landmarks(body).hips_y - float(full[lowest, 1].mean())), 1)
    return out

